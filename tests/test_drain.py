"""The launcher's end of a run (pure): it stops the nodes only once nothing is behind."""

from attention_bringup.drain import behind, logged_lines

DONE = {'handled_ns': 300, 'held': 0, 'given_feedback': 250, 'given_utterances': 12}
LOGGED = {'feedback': 250, 'utterance': 12}


def test_nothing_is_behind_once_the_last_step_is_judged_and_everything_given_is_logged():
    assert behind(DONE, 300, LOGGED) is None
    assert behind(DONE, 299, {'feedback': 251, 'utterance': 13}) is None  # copies: more


def test_each_way_of_being_behind_is_named():
    assert 'no trainer_status' in behind(None, 300, LOGGED)
    assert 'judged up to 299 ns of 300 ns' in behind(dict(DONE, handled_ns=299), 300, LOGGED)
    assert 'holds 3 messages' in behind(dict(DONE, held=3), 300, LOGGED)
    assert 'logged 249 of the 250 feedback' in behind(DONE, 300, dict(LOGGED, feedback=249))
    assert 'logged 0 of the 12 utterance' in behind(DONE, 300, {'feedback': 250})


def test_receipts_missed_at_the_start_are_made_up_by_the_learners_count_of_its_lines():
    # A short run on a busy machine: the launcher heard 34 of 296 receipts, the learner's
    # metrics say it logged all 296 (before, the launcher waited its full 60 s each such run).
    missed = {'feedback': 34, 'utterance': 12}
    counted = logged_lines({'log/feedback_lines': 250.0, 'log/utterance_lines': 12.0})
    assert counted == LOGGED
    assert 'logged 34 of the 250 feedback' in behind(DONE, 300, missed)
    assert behind(DONE, 300, missed, counted) is None
    assert 'logged 249 of the 250' in behind(DONE, 300, missed, dict(counted, feedback=249))
    assert logged_lines({}) == {'feedback': 0, 'utterance': 0}  # no metrics heard yet
