"""
Template matching and saliency images on real Room 1 frames along the scripted expert's route.

The frames come from the real emulator: the expert goes from the start to the key, a new episode
starts (the key is back) and the expert sets off again. Where the objects are is checked against
what the game says independently: the room's fixed layout, the agent's RAM position, the
skull's RAM position and whether the agent holds the key.
"""

from attention_tasks.montezuma.env import EnvConfig, MontezumaEnv
from attention_tasks.montezuma.expert import RoomOneExpert, SKULL_RAM, skull_x_from_ram
import cv2
import numpy as np
import pytest
from saliency_node.grounding import Grounder
from saliency_node.manifest import load_manifest, load_template_images
from saliency_node.matching import build_objects, method_from_name, SceneMatcher
from saliency_node.saliency import BLUR_RADIUS, gaussian_blur, SaliencyConfig, SaliencyMaker

# Room 1's layout: top-left corners of every instance (frame pixels).
LAYOUT = {
    'ladder': {(72, 96), (16, 139), (128, 139)},
    'rope': {(109, 93)},
    'door': {(20, 54), (136, 54)},
    'key': {(13, 99)},
    'conveyor': {(60, 136)},
    'platform': {(0, 93), (64, 93), (100, 93), (0, 136), (120, 136), (0, 180)},
}
REQUIRED = ('ladder', 'rope', 'door', 'key')  # found on every frame, even by a fresh matcher
AGENT_COLOURS = [(200, 72, 72), (210, 182, 86), (228, 111, 111), (240, 128, 128)]
SKULL_COLOUR = (236, 236, 236)
UTTERANCE = 'climb down the ladder and avoid the skull'


class Route:
    """Frames, RAM states, skull positions and expert phases of the route."""

    def __init__(self):
        self.frames, self.states, self.skulls, self.phases = [], [], [], []


@pytest.fixture(scope='module')
def route() -> Route:
    """Play the expert to the key, then start a new episode."""
    env = MontezumaEnv(EnvConfig(warmup_steps=0))
    expert = RoomOneExpert()
    result = Route()
    for steps_after_reset in (None, 30):  # to the key (and a little more), then a new start
        step = env.reset()
        expert.reset()
        done_for = 0
        while True:
            ram = env.ale.getRAM()
            action = expert.act(step.state, skull_x_from_ram(ram))
            result.frames.append(step.observation)
            result.states.append(step.state)
            result.skulls.append(int(ram[SKULL_RAM]))
            result.phases.append(expert.phase.name)
            done_for = done_for + 1 if step.state.has_key else 0
            count = len(result.frames)
            if done_for > 8 or step.done or (steps_after_reset and count > steps_after_reset
                                             + result.phases.index('DONE')):
                break
            step = env.step(action)
        assert 'DONE' in result.phases, 'the expert did not reach the key'
    env.close()
    return result


@pytest.fixture(scope='module')
def manifest():
    return load_manifest()


@pytest.fixture(scope='module')
def objects(manifest):
    return build_objects(manifest, load_template_images(manifest))


@pytest.fixture(scope='module')
def scenes(route, objects, manifest):
    matcher = SceneMatcher(objects, manifest.search_region, manifest.background)
    return [matcher.update(frame) for frame in route.frames]


def _corners(matches):
    return {(m.x, m.y) for m in matches}


def _key_drawn(frame) -> bool:
    """Tell whether the frame shows the key in the room (RAM has_key flips a frame early)."""
    return bool(np.all(frame[99:114, 13:20] == (232, 204, 99), axis=2).any())


def _expected(name, frame):
    return LAYOUT[name] if name != 'key' or _key_drawn(frame) else set()


def test_route_covers_the_poses_and_places_that_matter(route):
    phases = set(route.phases)
    for phase in ('DOWN_MIDDLE_LADDER', 'ON_ROPE', 'DOWN_RIGHT_LADDER', 'ACROSS_FLOOR',
                  'UP_LEFT_LADDER', 'AIRBORNE', 'DONE'):
        assert phase in phases
    has_key = [s.has_key for s in route.states]
    assert any(has_key) and not all(has_key) and not has_key[-1]  # taken, then back


def test_every_static_object_is_found_on_every_frame_with_no_false_match(route, scenes):
    for index, (scene, frame, state) in enumerate(zip(scenes, route.frames, route.states)):
        assert _key_drawn(frame) or state.has_key
        for name in LAYOUT:
            assert _corners(scene.matches[name]) == _expected(name, frame), (
                f'frame {index} ({route.phases[index]}): {name}')


def test_the_agent_and_the_skull_are_found_where_ram_puts_them(route, scenes):
    for index, (scene, state, skull) in enumerate(zip(scenes, route.states, route.skulls)):
        where = f'frame {index} ({route.phases[index]})'
        [agent] = scene.matches['agent']
        assert abs(state.x - (agent.x + 1)) <= 2, where
        assert abs((agent.y + agent.h) - (327 - state.y)) <= 5, where  # RAM y grows upward
        [found] = scene.matches['skull']
        assert abs(found.x + found.w / 2 - (skull + 36)) <= 1, where


def test_sprite_colours_belong_to_the_matched_sprite_only(route, scenes, manifest):
    x0, y0 = manifest.search_region[:2]
    for scene in scenes:
        for name in ('agent', 'skull'):
            pixels = scene.sprite_pixels[name].copy()
            for m in scene.matches[name]:
                pixels[m.y - y0:m.y - y0 + m.h, m.x - x0:m.x - x0 + m.w] = 0
            assert not pixels.any(), f'{name} colours outside its match'


def test_a_fresh_matcher_finds_the_required_objects_on_any_single_frame(route, objects,
                                                                        manifest):
    for index, frame in enumerate(route.frames[::2]):
        scene = SceneMatcher(objects, manifest.search_region).update(frame)
        for name in REQUIRED:
            assert _corners(scene.matches[name]) == _expected(name, frame), (
                f'frame {2 * index}: {name}')
        assert len(scene.matches['agent']) == 1 and len(scene.matches['skull']) == 1


# Saliency images ------------------------------------------------------------------------------

@pytest.fixture(scope='module')
def maker(objects, manifest):
    return SaliencyMaker(objects, manifest.search_region, manifest.background)


@pytest.fixture(scope='module')
def on_ladder(route, maker):
    """Return frame, scene and state with the agent on the middle ladder (route seen before)."""
    index = route.phases.index('DOWN_MIDDLE_LADDER') + 3
    for frame in route.frames[:index + 1]:
        scene = maker.observe(frame)
    return route.frames[index], scene, route.states[index]


def _colour_pixels(frame, colours, top=44):
    """Pixels of exactly these colours below the score, lives and inventory."""
    mask = np.zeros(frame.shape[:2], np.uint8)
    for colour in colours:
        mask |= cv2.inRange(frame, colour, colour)
    mask[:top] = 0
    return mask > 0


def _ladder_pixels(frame):
    mask = np.zeros(frame.shape[:2], bool)
    for x, y in LAYOUT['ladder']:
        h = 39 if (x, y) == (72, 96) else 41
        mask[y:y + h, x:x + 16] = np.all(frame[y:y + h, x:x + 16] == (66, 158, 130), axis=2)
    return mask


def _far_from(frame, masks, distance):
    near = np.zeros(frame.shape[:2], np.uint8)
    for mask in masks:
        near |= mask.astype(np.uint8)
    near = cv2.dilate(near, np.ones((2 * distance + 1, 2 * distance + 1), np.uint8))
    return near == 0


def test_language_keeps_ladder_skull_and_agent_and_blurs_the_rest(on_ladder, maker):
    frame, scene, _ = on_ladder
    named = Grounder.from_manifest(load_manifest()).ground(UTTERANCE).objects
    image, mask = maker.render(frame, scene, named, SaliencyConfig())
    ladder, skull = _ladder_pixels(frame), _colour_pixels(frame, [SKULL_COLOUR])
    agent = _colour_pixels(frame, AGENT_COLOURS)
    assert ladder.sum() > 500 and skull.sum() > 40 and agent.sum() > 60
    for kept in (ladder, skull, agent):
        assert np.array_equal(image[kept], frame[kept])
        assert mask[kept].all()
    far = _far_from(frame, [mask], BLUR_RADIUS)
    blurred = gaussian_blur(frame, BLUR_RADIUS)
    assert np.array_equal(image[far], blurred[far])
    assert (image[far] != frame[far]).any(axis=1).sum() > 1000  # the rest really is blurred
    key_box = np.zeros(frame.shape[:2], bool)
    key_box[99:114, 13:20] = True
    assert not mask[key_box].any()  # not named: not kept


def test_blind_agent_keeps_only_the_agent(on_ladder, maker):
    frame, scene, _ = on_ladder
    image, mask = maker.render(frame, scene, ('ladder', 'skull'), SaliencyConfig('blind_agent'))
    agent, ladder = _colour_pixels(frame, AGENT_COLOURS), _ladder_pixels(frame)
    assert np.array_equal(image[agent], frame[agent])
    assert (image[ladder] != frame[ladder]).any()
    far = _far_from(frame, [mask], BLUR_RADIUS)
    assert np.array_equal(image[far], gaussian_blur(frame, BLUR_RADIUS)[far])
    assert mask[~_far_from(frame, [agent], 1)].sum() == mask.sum()  # only at the agent


def test_an_utterance_naming_nothing_gives_the_blind_agent_map(on_ladder, maker):
    frame, scene, _ = on_ladder
    named = Grounder.from_manifest(load_manifest()).ground('well done, keep going').objects
    language, _ = maker.render(frame, scene, named, SaliencyConfig('language'))
    blind, _ = maker.render(frame, scene, (), SaliencyConfig('blind_agent'))
    assert np.array_equal(language, blind)


def test_hidden_agent_removes_the_agent_and_keeps_the_rest(route, on_ladder, maker):
    frame, scene, _ = on_ladder
    image, mask = maker.render(frame, scene, ('ladder',), SaliencyConfig('hidden_agent'))
    agent = _colour_pixels(frame, AGENT_COLOURS)
    assert not _colour_pixels(image, AGENT_COLOURS).any()  # no agent pixel anywhere
    assert not mask[agent].any()
    far = _far_from(frame, [agent], 4)
    assert np.array_equal(image[far], frame[far])
    # Where the agent was, the blurred room without it: as on a frame with the agent far away.
    elsewhere = route.frames[route.phases.index('ACROSS_FLOOR')]
    assert np.array_equal(image[agent], gaussian_blur(elsewhere, BLUR_RADIUS)[agent])


def test_faded_dims_instead_of_blurring(on_ladder, maker):
    frame, scene, _ = on_ladder
    image, mask = maker.render(frame, scene, ('skull',), SaliencyConfig('faded', fade=0.3))
    kept = mask > 0
    assert np.array_equal(image[kept], frame[kept])
    dimmed = np.clip(np.round(frame.astype(float) * 0.3), 0, 255).astype(np.uint8)
    assert np.abs(image[~kept].astype(int) - dimmed[~kept]).max() <= 1


def test_mask_mode_draws_the_mask_itself_white_on_black(on_ladder, maker):
    frame, scene, _ = on_ladder
    image, mask = maker.render(frame, scene, ('skull',), SaliencyConfig('mask'))
    language, same = maker.render(frame, scene, ('skull',), SaliencyConfig('language'))
    assert np.array_equal(mask, same) and mask.any() and not mask.all()
    assert image.shape == frame.shape and image.dtype == np.uint8
    assert (image[mask > 0] == 255).all() and (image[mask == 0] == 0).all()


def test_off_renders_nothing(on_ladder, maker):
    frame, scene, _ = on_ladder
    assert maker.render(frame, scene, ('ladder',), SaliencyConfig('off')) == (None, None)


def test_the_key_is_kept_while_present_and_not_after(route, objects, manifest):
    maker = SaliencyMaker(objects, manifest.search_region, manifest.background)
    kept_key = []
    for frame, state in zip(route.frames, route.states):
        scene = maker.observe(frame)
        _, mask = maker.render(frame, scene, ('key',), SaliencyConfig())
        yellow = np.all(frame[99:114, 13:20] == (232, 204, 99), axis=2)
        kept_key.append((_key_drawn(frame), bool((mask[99:114, 13:20] & yellow).any()),
                         bool(mask[:44].any())))
    assert all(drawn == kept for drawn, kept, _ in kept_key)
    assert any(drawn for drawn, _, _ in kept_key) and not all(d for d, _, _ in kept_key)
    assert not any(hud for _, _, hud in kept_key)  # the key in the inventory is not searched


def test_random_play_every_object_and_sprite_found(objects, manifest):
    """Seeded random actions: the agent falls, dies, jumps in place, in poses off the route."""
    env = MontezumaEnv(EnvConfig(warmup_steps=0, seed=1))
    rng = np.random.default_rng(1)
    matcher = SceneMatcher(objects, manifest.search_region, manifest.background)
    step = env.reset()
    for index in range(1000):
        frame = step.observation
        scene = matcher.update(frame)
        for name in LAYOUT:
            assert _corners(scene.matches[name]) == _expected(name, frame), f'{index}: {name}'
        for name, colours in (('agent', AGENT_COLOURS), ('skull', [SKULL_COLOUR])):
            visible = _colour_pixels(frame, colours).any()
            assert len(scene.matches[name]) == int(visible), f'{index}: {name}'
        step = env.step(int(rng.integers(18)))
        if step.done:
            step = env.reset()
    env.close()
    assert matcher.stats['sprite_searches'] > 0  # poses without a template were searched for


@pytest.mark.parametrize('method', ['TM_CCOEFF_NORMED', 'TM_SQDIFF_NORMED'])
def test_the_other_normalized_methods_find_the_same_objects(route, objects, manifest, method):
    matcher = SceneMatcher(objects, manifest.search_region, manifest.background,
                           method=method_from_name(method))
    for index, frame in enumerate(route.frames):
        scene = matcher.update(frame)
        for name in LAYOUT:
            assert _corners(scene.matches[name]) == _expected(name, frame), f'{index}: {name}'
        assert len(scene.matches['agent']) == 1 and len(scene.matches['skull']) == 1
