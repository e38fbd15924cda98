"""
saliency_node: utterances and observations in, saliency images (and their masks) out.

Every observation is matched against the templates as it arrives (cheap: the static objects
are cached, see ``matching``); an observation with a valid utterance (``timeline``) is rendered
in the callback and published on ``saliency`` with the observation's header. A whole render
takes well under a millisecond (``tests/benchmarks/bench_saliency.py``), so the work stays in
the callback: a worker thread would add a copy and a hand-off for nothing.
"""

import collections
import dataclasses
import functools
import time
import traceback

from attention_common import qos, topics
from attention_common.image_codec import image_to_numpy, ImageFormatError, numpy_to_image
from attention_common.node_main import run_node, StartupError
from attention_common.parameters import dataclass_specs
from attention_common.preview import Preview
from attention_common.recorder_gate import RecorderGate
from attention_common.stamps import NS_PER_S, stamp_to_ns, StampGuard
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from saliency_node.grounding import ascii_text, Grounder
from saliency_node.manifest import (frame_shape_for, load_backdrops, load_manifest,
                                    load_template_images, ManifestError, TemplateFileError)
from saliency_node.matching import build_objects, method_problem
from saliency_node.saliency import SaliencyConfig, SaliencyMaker
from saliency_node.settings import Settings, START_ONLY
from saliency_node.timeline import Timeline
from sensor_msgs.msg import Image
from std_msgs.msg import String


def _kept_alive(callback):
    """Log and count an unexpected error in a callback instead of letting it end the node."""
    @functools.wraps(callback)
    def guarded(self, msg):
        try:
            callback(self, msg)
        except Exception as error:  # noqa: B902 - a long run must survive one bad message
            self.counters['callback_errors'] += 1
            self.get_logger().error(f'{callback.__name__} failed and the message was dropped: '
                                    f'{error!r}\n{traceback.format_exc(limit=3)}')
    return guarded


class SaliencyNode(Node):
    """Language-guided template matching into saliency images."""

    def __init__(self, **kwargs):
        super().__init__('saliency_node', **kwargs)
        for name, (default, description) in dataclass_specs(Settings).items():
            # Dynamic typing: numbers may come as int or float, mode as YAML's false for off.
            self.declare_parameter(name, default, ParameterDescriptor(
                description=description, dynamic_typing=True))
        try:
            self.settings = Settings.from_values(self._values())
            manifest = load_manifest(self.settings.manifest_path)
            objects = build_objects(manifest, load_template_images(manifest),
                                    load_backdrops(manifest))
            self._frame_shape = frame_shape_for(manifest, self.settings.task_spec.frame_shape)
            problem = method_problem(objects, self.settings.method)
            if problem:
                raise ValueError(f'match_method: {problem}')
        except (TemplateFileError, ManifestError, ValueError) as error:
            raise StartupError(f'saliency_node: {error}') from None
        self._objects = objects
        self._maker = SaliencyMaker(objects, manifest.search_region, manifest.background,
                                    self.settings.method)
        self._grounder = Grounder.from_manifest(manifest)
        self._timeline = self._new_timeline()
        self._guard = StampGuard(self.settings.max_stamp_jump_ns)
        self._last_stamped = None  # (wall time, text) of the last stamped utterance
        self._recent_plain = None  # (wall time, text, Utterance) of the last plain one used
        self.counters = collections.Counter()
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self._saliency_pub = self.create_publisher(Image, topics.SALIENCY, qos.FRAMES_WRITER)
        self._mask_pub = self.create_publisher(Image, topics.SALIENCY_MASK, qos.FRAMES_WRITER)
        rate_hz = self.settings.preview_rate_hz
        self._saliency_preview = Preview(self, Image, topics.SALIENCY, rate_hz)
        self._mask_preview = Preview(self, Image, topics.SALIENCY_MASK, rate_hz)
        self._gate = RecorderGate(self, self.settings.wait_for_recorder,
                                  (self._saliency_pub, self._mask_pub),
                                  self.settings.wait_for_recorder_s)
        self.create_subscription(Image, topics.OBSERVATION, self._on_observation, qos.FRAMES)
        self.create_subscription(String, topics.UTTERANCE, self._on_utterance, qos.HUMAN)
        self.create_subscription(DiagnosticArray, topics.UTTERANCE_STAMPED,
                                 self._on_utterance_stamped, qos.HUMAN)
        self._status_timer = self.create_timer(  # wall time, whatever use_sim_time says
            self.settings.status_period, self._log_status,
            clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f'ready: mode {self.config.mode}, task {self.settings.task}, {len(objects)} objects '
            f'({", ".join(o.name for o in objects)}) from {self.settings.manifest_path}')

    @property
    def config(self) -> SaliencyConfig:
        return self.settings.saliency

    def _new_timeline(self) -> Timeline:
        return Timeline(self.settings.ttl_ns, self.settings.observation_buffer,
                        self.settings.require_utterance)

    # Parameters ---------------------------------------------------------------------------

    def _values(self, changes=None) -> dict:
        values = {f.name: self.get_parameter(f.name).value for f in dataclasses.fields(Settings)}
        values.update(changes or {})
        return values

    def _on_set_parameters(self, params) -> SetParametersResult:
        changes = {p.name: p.value for p in params}
        for name in START_ONLY:
            if name in changes:
                return SetParametersResult(successful=False,
                                           reason=f'{name} is read at start only')
        try:
            settings = Settings.from_values(self._values(changes))
        except ValueError as error:
            return SetParametersResult(successful=False, reason=str(error))
        problem = method_problem(self._objects, settings.method)
        if problem:
            return SetParametersResult(successful=False, reason=f'match_method: {problem}')
        old, self.settings = self.settings, settings
        if settings.saliency.mode != old.saliency.mode:
            self.get_logger().info(f'mode {old.saliency.mode} -> {settings.saliency.mode}')
            if settings.saliency.mode == 'off':
                self.counters['observations_dropped_off'] += self._timeline.clear_held()
        if settings.method != old.method:
            self._maker.matcher.set_method(settings.method)
        self._timeline.ttl_ns = settings.ttl_ns
        self._timeline.capacity = settings.observation_buffer
        self._timeline.require_utterance = settings.require_utterance
        self._guard.max_jump_ns = settings.max_stamp_jump_ns
        return SetParametersResult(successful=True)

    # Observations -------------------------------------------------------------------------

    @_kept_alive
    def _on_observation(self, msg: Image) -> None:
        stamp = stamp_to_ns(msg.header.stamp)
        try:
            if msg.encoding != 'rgb8':
                raise ImageFormatError(f'encoding {msg.encoding!r}, rgb8 expected')
            frame = image_to_numpy(msg, self._frame_shape)  # a wrong size is never copied
        except ImageFormatError as error:
            self.counters['observations_malformed'] += 1
            self.get_logger().error(
                f'observation at {stamp / NS_PER_S:.3f}s dropped: {error} '
                f'({self.counters["observations_malformed"]} malformed so far)')
            return
        if not self._on_timeline(stamp):
            return
        if self.config.mode == 'off':
            self.counters['observations_dropped_off'] += 1
            return
        scene = self._maker.observe(frame)
        self.counters['observations'] += 1
        held_before = self._timeline.dropped
        released = self._timeline.add_observation(stamp, (msg.header, frame, scene))
        if self._timeline.dropped > held_before:
            self.counters['observations_without_utterance'] += self._timeline.dropped - held_before
            self.get_logger().info(
                f'{self.counters["observations_without_utterance"]} observations so far had no '
                'valid utterance: no saliency image for them', throttle_duration_sec=30.0)
        if not released and self._timeline.held == 1:
            holding = (f'no utterance valid at {stamp / NS_PER_S:.3f}s: no saliency image until '
                       f'one is said (the last {self._timeline.capacity} observations are kept '
                       'for an utterance stamped with them that comes late)')
            if self.counters['utterances']:  # (rclpy wants one severity per call site)
                self.get_logger().debug(holding)
            else:
                self.get_logger().info(holding)
        self._render(released)

    def _on_timeline(self, stamp: int) -> bool:
        """Check an observation's stamp against the stream's (StampGuard); False: dropped."""
        verdict = self._guard.check(stamp)
        if verdict == 'implausible':
            self.counters['observations_implausible_stamp'] += 1
            self.get_logger().warning(
                f'observation at {stamp / NS_PER_S:.3f}s dropped: more than '
                f'{self.settings.max_stamp_jump_ns / NS_PER_S:g} s from the newest '
                f'({self.counters["observations_implausible_stamp"]} so far)')
            return False
        if verdict == 'restart':
            self.counters['stamp_restarts'] += 1
            self.counters['observations_dropped_restart'] += self._timeline.held
            self._timeline = self._new_timeline()
            self.get_logger().warning(
                f'observation stamps started over at {stamp / NS_PER_S:.3f}s (a new env): '
                'utterances and held observations of the old timeline are forgotten')
        return True

    def _render(self, released) -> None:
        for release in released:
            header, frame, scene = release.item
            named = release.utterance.payload if release.utterance else ()
            image, mask = self._maker.render(frame, scene, named, self.config)
            if image is None:
                continue
            saliency = self._image(image, 'rgb8', header)
            self._gate.publish(self._saliency_pub, saliency)
            self._saliency_preview.publish(saliency)
            if self.settings.publish_mask:
                self._publish_mask(mask, header)
            self.counters['saliency_published'] += 1

    def _publish_mask(self, mask, header) -> None:
        """Render the mask only for a reader (while the gate holds, the recorder is one)."""
        def image() -> Image:
            return self._image(mask * 255, 'mono8', header)

        if not self._gate.is_open or self._mask_pub.get_subscription_count():
            msg = image()
            self._gate.publish(self._mask_pub, msg)
            self._mask_preview.publish(msg)
        else:
            self._mask_preview.publish(image)  # made only if a viewer takes it

    @staticmethod
    def _image(array, encoding, header) -> Image:
        msg = numpy_to_image(array, encoding, Image())
        msg.header = header
        return msg

    # Utterances ---------------------------------------------------------------------------

    # The synthetic trainer publishes each utterance twice: on utterance_stamped and, for
    # viewers, as a plain utterance; the two can arrive in either order. A plain utterance is
    # its copy when a stamped one with the same text came within stamped_stream_timeout (wall);
    # a copy that came first is withdrawn. A person's words of another text are always heard.

    @_kept_alive
    def _on_utterance(self, msg: String) -> None:
        text = self._checked_text(msg.data, 'utterance')
        if text is None:
            return
        now = time.monotonic()
        window = self.settings.stamped_stream_timeout
        if (self._last_stamped is not None and now - self._last_stamped[0] < window
                and self._last_stamped[1] == text):
            self.counters['utterances_duplicate'] += 1
            self.get_logger().debug(f'plain utterance {text[:80]!r} is the copy of the stamped '
                                    'one just heard: used once')
            return
        utterance = self._accept(text, None, 'utterance')
        self._recent_plain = (now, text, utterance)

    @_kept_alive
    def _on_utterance_stamped(self, msg: DiagnosticArray) -> None:
        if not msg.status or msg.status[0].name != 'utterance':
            self.counters['utterances_malformed'] += 1
            self.get_logger().error(
                'utterance_stamped dropped: status[0].name must be "utterance" '
                f'(got {[s.name for s in msg.status][:3]})')
            return
        text = self._checked_text(msg.status[0].message, 'utterance_stamped')
        if text is None:
            return
        stamp = stamp_to_ns(msg.header.stamp)
        if not self._guard.plausible(stamp):
            self.counters['utterances_implausible_stamp'] += 1
            self.get_logger().warning(
                f'utterance_stamped {text[:80]!r} dropped: its stamp {stamp / NS_PER_S:.3f}s '
                f'is more than {self.settings.max_stamp_jump_ns / NS_PER_S:g} s from the newest '
                f'observation ({self._guard.newest / NS_PER_S:.3f}s)')
            return
        now = time.monotonic()
        self._last_stamped = (now, text)
        if self._recent_plain is not None:
            wall, plain_text, plain = self._recent_plain
            if plain_text == text and now - wall < self.settings.stamped_stream_timeout:
                self._timeline.discard(plain)  # its copy came first: keep the stamped one
                self.counters['utterances_duplicate'] += 1
                self.counters['utterances'] -= 1
                self.get_logger().debug(f'plain utterance {text[:80]!r} was the copy of this '
                                        'stamped one: withdrawn')
            self._recent_plain = None
        self._accept(text, stamp, 'utterance_stamped')

    def _accept(self, text: str, stamp_ns, source: str):
        grounding = self._grounder.ground(text)
        self.counters['utterances'] += 1
        when = 'now' if stamp_ns is None else f'{stamp_ns / NS_PER_S:.3f}s'
        self.get_logger().info(f'{source} at {when}: {text[:120]!r} -> '
                               f'{", ".join(grounding.objects)}')
        if not grounding.named:
            self.get_logger().debug(f'{text[:120]!r} names no known object: agent only '
                                    '(blind agent map)')
        utterance, released = self._timeline.add_utterance(text, stamp_ns, grounding.objects)
        self._render(released)
        return utterance

    def _checked_text(self, text: str, source: str):
        """Return the text to use, or None (logged and counted) if it cannot be used."""
        if len(text) > self.settings.max_utterance_chars:
            self.counters['utterances_too_long'] += 1
            self.get_logger().error(f'{source} dropped: {len(text)} characters, more than '
                                    f'max_utterance_chars={self.settings.max_utterance_chars}')
            return None
        if not text.strip():
            self.counters['utterances_empty'] += 1
            self.get_logger().warning(f'{source} dropped: empty or only whitespace')
            return None
        if not text.isascii():
            folded = ' '.join(ascii_text(text).split())
            if not any(c.isalpha() for c in folded):
                self.counters['utterances_non_ascii'] += 1
                self.get_logger().error(f'{source} dropped: no ASCII words in {text[:80]!r}')
                return None
            self.counters['utterances_folded'] += 1
            self.get_logger().warning(f'{source} has non-ASCII characters; using {folded!r}')
            return folded
        return text

    def _log_status(self) -> None:
        if self.counters:
            summary = ', '.join(f'{k} {v}' for k, v in sorted(self.counters.items()))
            stats = self._maker.matcher.stats
            self.get_logger().info(f'{summary}; held {self._timeline.held}; full searches '
                                   f'{stats["full_searches"]} in {stats["frames"]} frames')


def main(args=None):
    return run_node(SaliencyNode, args=args)


if __name__ == '__main__':
    raise SystemExit(main())
