"""
Topic names of the graph, in one place.

Names are relative, so a namespace (``--ros-args -r __ns:=/trial3``) or a remap moves them.
Only ``/clock`` is absolute: ROS 2 time sources listen there.
"""

OBSERVATION = 'observation'          # sensor_msgs/Image rgb8 210x160, env -> saliency, tamer
AGENT_POSITION = 'agent_position'    # geometry_msgs/PointStamped x, y, z=room, env -> feedback
ACTION = 'action'                    # sensor_msgs/Joy stamped with the observation it answers
# sensor_msgs/Joy: the action the world executed on a step, when the learner did not choose it
# (attention_replay: the recorded session's); the tamer learns the feedback on that action
ACTION_TAKEN = 'action_taken'
ENV_STATUS = 'env_status'            # diagnostic_msgs/DiagnosticArray, one per step
CLOCK = '/clock'                     # rosgraph_msgs/Clock, simulation time, env -> all

UTTERANCE = 'utterance'              # std_msgs/String, feedback node or a person
UTTERANCE_STAMPED = 'utterance_stamped'  # diagnostic_msgs/DiagnosticArray, synthetic trainer
FEEDBACK = 'feedback'                # std_msgs/Float32 scalar h, feedback node or a person
FEEDBACK_STAMPED = 'feedback_stamped'    # geometry_msgs/Vector3Stamped, synthetic trainer
# geometry_msgs/Vector3Stamped, x = h, header = the moment it was given (simulation time), not
# the step judged: a late trainer's press (feedback_node press_times)
FEEDBACK_PRESSED = 'feedback_pressed'
# diagnostic_msgs/DiagnosticArray, latched: how far the synthetic trainer got (the newest step
# judged from, what it gave, what it holds, its counts); the launcher's end waits on it
TRAINER_STATUS = 'trainer_status'

SALIENCY = 'saliency'                # sensor_msgs/Image rgb8, same stamp as its observation
SALIENCY_MASK = 'saliency_mask'      # sensor_msgs/Image mono8 debug view of the mask

METRICS = 'metrics'                  # diagnostic_msgs/DiagnosticArray, learner metrics
# diagnostic_msgs/DiagnosticArray, one per feedback or utterance line the learner logged (the
# trainer console's receipt: it names the message by its publisher's sequence number)
FEEDBACK_LOGGED = 'feedback_logged'
# diagnostic_msgs/DiagnosticArray, one per step the learner acted on (only while someone listens):
# header = the step, the action taken and H for each action (what the person sees it think)
ACTION_VALUES = 'action_values'
# diagnostic_msgs/DiagnosticArray, one per feedback learned from: its seq and the steps its
# credit went to, with their weights (the console's strip under the frame)
FEEDBACK_CREDIT = 'feedback_credit'
# geometry_msgs/Vector3Stamped, tamer -> trainer: the learner asks about the step of the header
# (x = the action it took, y = the gap between H's two best actions); the trainer answers on
# feedback_stamped with that stamp
QUESTION = 'question'
