"""
Saliency on DoorKey, on real MiniGrid frames.

Colour templates, grounding, masks, the template command, the task parameter, and the real node
over topics with ``task:=doorkey``.
"""

from pathlib import Path
import shutil
import subprocess
import sys

from attention_common import qos, topics
from attention_common.image_codec import image_to_numpy, numpy_to_image
from attention_common.stamps import NS_PER_S, ns_to_stamp, stamp_to_ns
from attention_tasks.doorkey.env import DoorKeyEnv, DoorKeyEnvConfig
from attention_tasks.doorkey.expert import next_action
from attention_tasks.doorkey.language import sentence
from attention_tasks.doorkey.make_templates import wanted_files
from attention_tasks.doorkey.task import TASK
import cv2
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from minigrid.core.constants import COLOR_NAMES
import numpy as np
import pytest
from saliency_node.grounding import Grounder
from saliency_node.manifest import (DEFAULT_MANIFEST, frame_shape_for, load_backdrops,
                                    load_manifest, load_template_images, ManifestError)
from saliency_node.matching import build_objects, match_scene, method_problem, SceneMatcher
from saliency_node.saliency import SaliencyConfig, SaliencyMaker
from saliency_node.settings import Settings
from sensor_msgs.msg import Image
import yaml

BIN = Path(sys.executable).parent
TILE = 16
KINDS = ('key', 'ball', 'box')


@pytest.fixture(scope='module')
def manifest():
    return load_manifest(TASK.manifest)


@pytest.fixture(scope='module')
def objects(manifest):
    return build_objects(manifest, load_template_images(manifest), load_backdrops(manifest))


def truth(world):
    """Return object name -> top-left pixels of its cells in the agent's view (the agent's)."""
    grid, _ = world.gen_obs_grid()  # what observe draws: hidden cells empty, the carried object
    found = {}                      # in the agent's cell
    for i in range(grid.width):
        for j in range(grid.height):
            cell = grid.get(i, j)
            if cell is not None and cell.type != 'wall':
                name = 'green square' if cell.type == 'goal' else f'{cell.color} {cell.type}'
                found.setdefault(name, set()).add((i * TILE, j * TILE))
    found['agent'] = {(grid.width // 2 * TILE, (grid.height - 1) * TILE)}
    return found


def play(episodes, seed, steps, random_share):
    """Yield (frame, truth, state): the expert with random actions mixed in, layout by layout."""
    env = DoorKeyEnv(DoorKeyEnvConfig(seed=seed))
    rng = np.random.default_rng(seed)
    try:
        for _ in range(episodes):
            step = env.reset()
            yield step.observation, truth(env.world), step.state
            for _ in range(steps):
                action = next_action(env.world)
                if action is None or rng.random() < random_share:
                    action = int(rng.integers(6))
                step = env.step(action)
                yield step.observation, truth(env.world), step.state
                if step.done:
                    break
    finally:
        env.close()


@pytest.fixture(scope='module')
def frames():
    """Play 200 layouts a few steps each, and 12 to the goal (keys carried, doors open)."""
    return (list(play(200, seed=11, steps=8, random_share=0.5))
            + list(play(12, seed=12, steps=200, random_share=0.15)))


def cell_looks(frames):
    """Every distinct cell seen in the frames: (the objects on it, 16 x 16 RGB), floor too."""
    looks = {}
    for frame, where, _ in frames:
        names = {}
        for name, cells in where.items():
            for cell in cells:
                names.setdefault(cell, set()).add(name)
        for y in range(0, frame.shape[0], TILE):
            for x in range(0, frame.shape[1], TILE):
                pixels = frame[y:y + TILE, x:x + TILE]
                looks.setdefault(pixels.tobytes(),
                                 (frozenset(names.get((x, y), ())), pixels.copy()))
    return list(looks.values())


def aligned_score(template, cell, gray=False):
    if gray:
        template, cell = (cv2.cvtColor(a, cv2.COLOR_RGB2GRAY) for a in (template, cell))
    return float(cv2.matchTemplate(cell, template, cv2.TM_CCORR_NORMED)[0, 0])


def best_other(objects, looks, name, gray=False):
    """Return the best score of ``name``'s templates on other objects' cells, and those."""
    model = next(o for o in objects if o.name == name)
    return max((aligned_score(t.rgb, pixels, gray), ', '.join(sorted(here)))
               for here, pixels in looks if name not in here for t in model.templates)


# Colour matching -------------------------------------------------------------------------------

def test_templates_of_one_colour_score_well_below_threshold_on_other_colours(frames, objects):
    """Every cell is matched on the grid: the scores between cells decide it all."""
    looks = cell_looks(frames)
    seen = {here for here, _ in looks}
    assert {frozenset([f'{c} {k}']) for c in COLOR_NAMES for k in KINDS} <= seen
    assert sum('agent' in here and len(here) == 2 for here in seen) >= 12  # carrying
    assert frozenset() in seen and frozenset(['green square']) in seen
    for obj in objects:
        score, other = best_other(objects, looks, obj.name)
        assert score < obj.threshold - 0.002, (obj.name, other, score)
    # The closest colours, grey and purple (under the agent); red on purple; the red agent.
    assert best_other(objects, looks, 'grey key')[0] < 0.996
    for kind in KINDS:
        red = next(o for o in objects if o.name == f'red {kind}').templates[0].rgb
        purple = next(p for here, p in looks if here == {f'purple {kind}'})
        assert aligned_score(red, purple) < 0.93
        assert aligned_score(red, purple, gray=True) > 0.9999  # luma cannot tell them apart
    assert best_other(objects, looks, 'agent')[0] < 0.98


def test_luma_cannot_tell_the_colours_apart(frames, objects):
    looks = cell_looks(frames)
    for kind in KINDS:
        score, other = best_other(objects, looks, f'purple {kind}', gray=True)
        assert score > 0.9999 and other.endswith(kind), (kind, other, score)


def test_matching_finds_every_object_of_its_colour_and_nothing_else(frames, objects, manifest):
    """One matcher over every frame, as the node sees them: layout after layout."""
    matcher = SceneMatcher(objects, manifest.search_region, manifest.background)
    counts = {'hits': 0, 'misses': 0, 'false positives': 0}
    wrong = []
    for index, (frame, where, _) in enumerate(frames):
        scene = matcher.update(frame)
        for obj in objects:
            found = {(m.x, m.y) for m in scene.matches[obj.name]}
            wanted = where.get(obj.name, set())
            counts['hits'] += len(found & wanted)
            counts['misses'] += len(wanted - found)
            counts['false positives'] += len(found - wanted)
            if found != wanted:
                wrong.append((index, obj.name, sorted(found), sorted(wanted)))
        if index % 40 == 0:  # the cached matcher finds what a search of everything finds
            reference = match_scene(frame, objects, manifest.search_region)
            assert {n: sorted((m.x, m.y) for m in ms) for n, ms in reference.items()} == {
                n: sorted((m.x, m.y) for m in ms) for n, ms in scene.matches.items()}
    assert counts['misses'] == 0 and counts['false positives'] == 0, (counts, wrong[:5])
    assert counts['hits'] > 3 * len(frames)  # the agent and what it sees: 3.75 a frame
    assert matcher.stats['full_searches'] == 1


def test_the_other_bounded_method_works_with_the_same_thresholds(frames, objects):
    matcher = SceneMatcher(objects, method=cv2.TM_SQDIFF_NORMED)
    for frame, where, _ in frames[-150:]:
        scene = matcher.update(frame)
        assert {n: {(m.x, m.y) for m in ms} for n, ms in scene.matches.items() if ms} == where


# Grounding ------------------------------------------------------------------------------------

@pytest.mark.parametrize('utterance, named', [
    ('pick up the yellow key', ('yellow key',)),
    ('open the yellow door', ('yellow door',)),
    ('go to the green square', ('green square',)),
    ('drop the blue ball and pick up the yellow key', ('yellow key', 'blue ball')),
    ('Pick up the GRAY box!', ('grey box',)),
])
def test_the_teachers_sentences_name_exactly_their_objects(manifest, utterance, named):
    grounding = Grounder.from_manifest(manifest).ground(utterance)
    assert grounding.named == named and grounding.objects == named + ('agent',)


def test_every_sentence_of_the_teacher_grounds_in_what_it_names(frames, manifest):
    grounder = Grounder.from_manifest(manifest)
    for _, _, state in frames:
        text = sentence(state)
        wanted = {f'{state.door_color} key'} if 'key' in text else set()
        if 'door' in text:
            wanted.add(f'{state.door_color} door')
        if text.startswith('drop'):
            wanted.add(state.carrying)
        if 'square' in text:
            wanted.add('green square')
        assert set(grounder.ground(text).named) == wanted, text


# Saliency images ------------------------------------------------------------------------------

def foreground(objects, manifest, frame, name):
    """Return the frame's pixels of ``name``'s matches (their templates' foreground)."""
    scene = SceneMatcher(objects, manifest.search_region, manifest.background).update(frame)
    return SaliencyMaker(objects).mask(frame.shape, scene, [name]).astype(bool)


def distractors(where, named):
    return [n for n in where if n.endswith(KINDS) and n not in named]


def test_the_saliency_image_keeps_the_named_key_and_the_agent_and_blurs_a_distractor(
        frames, objects, manifest):
    frame, where, state = next(
        (f, w, s) for f, w, s in frames if sentence(s).startswith('pick up')
        and f'{s.door_color} key' in w and distractors(w, [f'{s.door_color} key']))
    key = f'{state.door_color} key'
    named = Grounder.from_manifest(manifest).ground(sentence(state)).objects
    maker = SaliencyMaker(objects, manifest.search_region, manifest.background)
    scene = maker.observe(frame)
    image, mask = maker.render(frame, scene, named, SaliencyConfig(mode='language'))
    assert image.shape == frame.shape == TASK.frame_shape + (3,)
    assert mask.shape == TASK.frame_shape
    for name in (key, 'agent'):
        pixels = foreground(objects, manifest, frame, name)
        assert 20 < pixels.sum() < 120, name  # its own pixels, not its cell's floor
        assert np.array_equal(image[pixels], frame[pixels]), name
    for name in distractors(where, [key]):
        pixels = foreground(objects, manifest, frame, name)
        assert (image[pixels] != frame[pixels]).any(axis=1).mean() > 0.5, name
    agent = foreground(objects, manifest, frame, 'agent')
    hidden, keep = maker.render(frame, scene, named, SaliencyConfig(mode='hidden_agent'))
    assert not keep[agent].any()
    redness = [(picture[agent][:, 0].astype(int) - picture[agent][:, 1]).mean()
               for picture in (frame, hidden)]
    assert redness[0] > 120 and redness[1] < 30  # no red smudge left


def test_a_carried_ball_is_the_ball_and_the_agent_only_the_triangle(frames, objects, manifest):
    frame, where, state = next(
        (f, w, s) for f, w, s in frames
        if s.carrying.endswith(('ball', 'box')) and not s.door_open)
    agent = foreground(objects, manifest, frame, 'agent')
    carried = foreground(objects, manifest, frame, state.carrying)
    assert where[state.carrying] >= where['agent']  # in the agent's cell, under it
    assert 20 < agent.sum() < 120 and (carried & ~agent).sum() > 10
    named = Grounder.from_manifest(manifest).ground(sentence(state)).objects
    assert state.carrying in named  # "drop the ... and pick up ..."


# Templates ------------------------------------------------------------------------------------

def test_the_command_renders_exactly_the_committed_templates(tmp_path):
    folder = TASK.manifest.parent
    out = tmp_path / 'out'
    result = subprocess.run([str(BIN / 'doorkey_make_templates'), '--out', str(out)],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    committed = sorted(p.name for p in folder.glob('*.png'))
    named = wanted_files(yaml.safe_load(TASK.manifest.read_text()))
    assert sorted(p.name for p in out.glob('*.png')) == committed == sorted(named)
    for name in committed:
        assert np.array_equal(cv2.imread(str(out / name)), cv2.imread(str(folder / name))), name
    check = subprocess.run([str(BIN / 'doorkey_make_templates'), '--check'],
                           capture_output=True, text=True, timeout=120)
    assert check.returncode == 0, check.stderr


def test_check_names_a_changed_template_and_a_look_without_one(tmp_path):
    folder = tmp_path / 'templates'
    shutil.copytree(TASK.manifest.parent, folder)
    image = cv2.imread(str(folder / 'red_key.png'))
    image[8, 8] = 255 - image[8, 8]
    cv2.imwrite(str(folder / 'red_key.png'), image)
    path = folder / 'manifest.yaml'
    command = [str(BIN / 'doorkey_make_templates'), '--manifest', str(path)]

    def check():
        result = subprocess.run(command + ['--check'], capture_output=True, text=True,
                                timeout=120)
        return result.returncode, result.stderr

    assert check() == (1, 'red_key.png differs from a fresh render\n')
    assert subprocess.run(command, capture_output=True, timeout=120).returncode == 0
    assert check() == (0, '')
    raw = yaml.safe_load(path.read_text())
    del raw['objects']['purple ball']
    path.write_text(yaml.safe_dump(raw))
    assert check() == (1, 'no template shows purple ball\n')


# The task parameter ---------------------------------------------------------------------------

def test_the_task_names_the_manifest_and_the_frame_size(manifest):
    assert Settings.from_values({}).manifest_path == DEFAULT_MANIFEST
    assert Settings.from_values({'task': 'doorkey'}).manifest_path == TASK.manifest
    assert frame_shape_for(manifest, TASK.frame_shape) == TASK.frame_shape
    assert manifest.source == 'minigrid' and manifest.search_region is None
    with pytest.raises(ManifestError, match=r'\[210, 160\] frames'):
        frame_shape_for(load_manifest(), TASK.frame_shape)


def test_the_goal_cannot_be_matched_by_tm_ccoeff_normed(objects):
    assert method_problem(objects, cv2.TM_CCORR_NORMED) == ''
    assert 'cannot match green square' in method_problem(objects, cv2.TM_CCOEFF_NORMED)


def test_an_unknown_task_names_the_installed_ones():
    with pytest.raises(ValueError, match=r"unknown task 'pong'; installed tasks: .*doorkey.*"
                                         r'montezuma'):
        Settings.from_values({'task': 'pong'})


# The node over topics -------------------------------------------------------------------------

def yellow_key_in_view():
    """Return the first frame (and truth) of the expert's on which a yellow door's key shows."""
    for frame, where, state in play(100, seed=0, steps=20, random_share=0.0):
        if state.door_color == 'yellow' and 'yellow key' in where and not state.carrying:
            return frame, where
    raise AssertionError('no yellow key in view in 100 layouts')


@pytest.mark.topics
def test_the_node_with_task_doorkey_keeps_the_yellow_key(start_node, probe, objects, manifest):
    frame, where = yellow_key_in_view()
    node = start_node('saliency_node', {'task': 'doorkey'})
    observation = probe.publisher(Image, topics.OBSERVATION, qos.FRAMES)
    stamped = probe.publisher(DiagnosticArray, topics.UTTERANCE_STAMPED, qos.HUMAN)
    saliency = probe.subscribe(Image, topics.SALIENCY, qos.FRAMES)
    for publisher in (observation, stamped):
        assert probe.wait_for_subscribers(publisher, timeout=20.0), node.log_text()[-2000:]
    assert probe.wait_for_publishers(topics.SALIENCY, timeout=20.0)
    assert node.wait_for_log('ready: mode language, task doorkey', 20.0)
    stamp = 1 * NS_PER_S
    msg = numpy_to_image(frame, 'rgb8', Image())
    msg.header.stamp = ns_to_stamp(stamp)
    observation.publish(msg)
    assert node.wait_for_log('no utterance valid', 15.0), node.log_text()[-2000:]
    said = DiagnosticArray()
    said.header.stamp = ns_to_stamp(stamp)
    said.status = [DiagnosticStatus(name='utterance', message='pick up the yellow key')]
    stamped.publish(said)
    assert saliency.wait_for(lambda ms: any(stamp_to_ns(m.header.stamp) == stamp for m in ms),
                             15.0), node.log_text()[-2000:]
    image = image_to_numpy(saliency.snapshot()[0])
    assert image.shape == TASK.frame_shape + (3,)
    for name in ('yellow key', 'agent'):
        pixels = foreground(objects, manifest, frame, name)
        assert np.array_equal(image[pixels], frame[pixels]), name
    others = [n for n in where if n.endswith(KINDS) and n != 'yellow key']
    changed = [foreground(objects, manifest, frame, n) for n in others]
    assert all((image[p] != frame[p]).any(axis=1).mean() > 0.5 for p in changed)
    assert '-> yellow key, agent' in node.log_text()
    assert node.stop() == 0


@pytest.mark.topics
def test_the_node_refuses_an_unknown_task(start_node):
    node = start_node('saliency_node', {'task': 'pong'})
    assert node.process.wait(timeout=30) == 1
    assert "unknown task 'pong'; installed tasks:" in node.log_text()
