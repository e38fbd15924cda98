"""saliency_node's pure core on plain arrays: grounding, matching, images, timing, manifest."""

from dataclasses import fields
from pathlib import Path
import shutil

from attention_common.parameters import field_docs
import cv2
import numpy as np
import pytest

from saliency_node.grounding import Grounder, stem, tokenize
from saliency_node.manifest import (load_manifest, load_template_images, ManifestError,
                                    parse_route, TemplateFileError)
from saliency_node.matching import (find_matches, Match, method_from_name, non_max_suppression,
                                    ObjectModel, SceneMatcher, Template)
from saliency_node.saliency import compose, gaussian_blur, parse_mode, SaliencyConfig
from saliency_node.settings import Settings
from saliency_node.timeline import Timeline

S = 1_000_000_000


@pytest.fixture(scope='module')
def grounder():
    return Grounder.from_manifest(load_manifest())


# Grounding ------------------------------------------------------------------------------------

@pytest.mark.parametrize('word, expected', [
    ('Ladders', 'ladder'), ('ladder', 'ladder'), ('stairs', 'stair'), ('enemies', 'enemy'),
    ('climbing', 'climb'), ('climbed', 'climb'), ('climbs', 'climb'), ('downs', 'down'),
    ('gates', 'gate'), ('keys', 'key'), ('boxes', 'box'), ('glass', 'glass'), ('key', 'key'),
])
def test_stem_drops_plural_and_verb_endings(word, expected):
    assert stem(word) == expected


def test_tokenize_ignores_case_punctuation_and_accents():
    assert tokenize('Climb downs the LADDERS!') == ['climb', 'down', 'the', 'ladder']
    assert tokenize('Cl\u00edmb... the l\u00e4dder, quick') == ['climb', 'the', 'ladder', 'quick']
    assert tokenize('  \t ') == []


@pytest.mark.parametrize('utterance, named', [
    ('Climb downs the ladders!', {'ladder'}),
    ('Climb downs the ladder and avoid the skull', {'ladder', 'skull'}),
    ('Go back to the top of the ladder and jump onto the rope.', {'ladder', 'rope'}),
    ('Jump right from the ladder onto the rope.', {'ladder', 'rope'}),
    ('Jump right from the rope onto the lower platform.', {'rope', 'platform'}),
    ('Climb down the ladder onto the ground.', {'ladder', 'platform'}),
    ('Move left and avoid the skull.', {'skull'}),
    ('Climb up the ladder.', {'ladder'}),
    ('Jump up to get the key.', {'key'}),
    ('Open the gate', {'door'}), ('open the DOORS', {'door'}),
    ('take the stairs', {'ladder'}), ('watch out for the enemy', {'skull'}),
    ('swing on the vine', {'rope'}), ('stay on the floor', {'platform'}),
    ('ride the conveyor belt', {'conveyor'}),
    ('keys? doors!', {'key', 'door'}),
    ('the quick brown fox', set()), ('', set()), ('!!! ???', set()),
])
def test_grounding_table(grounder, utterance, named):
    grounding = grounder.ground(utterance)
    assert set(grounding.named) - {'agent'} == named
    assert set(grounding.objects) == named | {'agent'}  # the agent is always selected


def test_grounding_phrases_and_unknown_words():
    grounder = Grounder({'skull': ['bad guy', 'enemy'], 'me': ['player']}, agent='me')
    assert grounder.ground('the bad guys are coming').named == ('skull',)
    assert grounder.ground('bad luck, guy').named == ()  # not adjacent: not the phrase
    assert grounder.ground('xyzzy plugh').objects == ('me',)


# Matching -------------------------------------------------------------------------------------

def test_method_from_name():
    assert method_from_name('TM_CCORR_NORMED') == cv2.TM_CCORR_NORMED
    assert method_from_name('tm_sqdiff_normed') == cv2.TM_SQDIFF_NORMED
    with pytest.raises(ValueError, match='TM_CCORR_NORMED'):
        method_from_name('TM_CCORR')


def test_non_max_suppression_keeps_best_of_overlapping_and_all_separate():
    a = Match('o', 0, 10, 10, 8, 8, 0.95)
    a_shifted = Match('o', 0, 12, 10, 8, 8, 0.90)
    b = Match('o', 0, 40, 10, 8, 8, 0.91)
    touching = Match('o', 0, 18, 10, 8, 8, 0.92)  # shares an edge with a, no pixel
    kept = non_max_suppression([a_shifted, b, a, touching])
    assert kept == [a, touching, b]
    assert non_max_suppression([a, a_shifted], overlap=0.7) == [a, a_shifted]


def _pattern():
    rng = np.random.default_rng(1)
    return rng.integers(40, 255, size=(5, 4), dtype=np.uint8)


@pytest.mark.parametrize('method', ['TM_CCORR_NORMED', 'TM_CCOEFF_NORMED', 'TM_SQDIFF_NORMED'])
def test_find_matches_finds_every_copy(method):
    image = np.zeros((30, 40), np.uint8)
    pattern = _pattern()
    spots = [(2, 3), (20, 3), (10, 22)]
    for x, y in spots:
        image[y:y + 5, x:x + 4] = pattern
    found = non_max_suppression(find_matches(image, pattern, 0.99, method_from_name(method)))
    assert sorted((m.x, m.y) for m in found) == sorted(spots)
    assert all(m.score >= 0.99 for m in found)


def _scene_objects():
    rng = np.random.default_rng(2)
    palette = np.array([(66, 158, 130), (24, 59, 157), (0, 0, 0)], np.uint8)  # not the sprite's
    wall = palette[rng.integers(0, 3, size=(6, 5))]
    sprite = np.zeros((4, 3, 3), np.uint8)
    sprite[1:, :] = (200, 72, 72)
    sprite[0, 1] = (210, 182, 86)
    return (ObjectModel('wall', [Template(wall)], threshold=0.99),
            ObjectModel('me', [Template(sprite)], threshold=0.9, moves=True, agent=True),
            wall, sprite)


def test_scene_matcher_tracks_a_sprite_and_a_static_object_it_passes():
    wall_model, me_model, wall, sprite = _scene_objects()
    frame = np.zeros((30, 40, 3), np.uint8)
    frame[10:16, 20:25] = wall
    matcher = SceneMatcher([wall_model, me_model], (0, 0, 40, 30))
    for x in range(2, 34, 3):  # the sprite walks across, in front of the wall
        shown = frame.copy()
        region = shown[12:16, x:x + 3]
        sprite_pixels = np.any(sprite > 0, axis=2)
        region[sprite_pixels] = sprite[sprite_pixels]
        scene = matcher.update(shown)
        assert [(m.x, m.y) for m in scene.matches['me']] == [(x, 12)]
        assert [(m.x, m.y) for m in scene.matches['wall']] == [(20, 10)]
    gone = frame.copy()
    gone[10:16, 20:25] = 0
    assert matcher.update(gone).matches['wall'] == []
    assert [(m.x, m.y) for m in matcher.update(frame).matches['wall']] == [(20, 10)]


# Images ---------------------------------------------------------------------------------------

@pytest.mark.parametrize('value, mode', [
    ('language', 'language'), ('OFF', 'off'), (' faded ', 'faded'), (False, 'off'),
    ('blind_agent', 'blind_agent'), ('hidden_agent', 'hidden_agent'),
])
def test_parse_mode_reads_yaml_off_as_false(value, mode):
    assert parse_mode(value) == mode


@pytest.mark.parametrize('value', [True, 'on', '', 3, None])
def test_parse_mode_rejects_others(value):
    with pytest.raises(ValueError, match='language'):
        parse_mode(value)


@pytest.mark.parametrize('kwargs', [
    {'blur_radius': -1}, {'blur_radius': 2.5}, {'fade': 1.5}, {'blur_sigma': -1.0},
    {'mode': 'loud'},
])
def test_saliency_config_rejects_bad_values(kwargs):
    with pytest.raises(ValueError):
        SaliencyConfig(**kwargs)


@pytest.mark.parametrize('radius', [1, 3, 5])
def test_gaussian_blur_is_cv2_gaussian_blur_within_rounding(radius):
    rng = np.random.default_rng(radius)
    frame = rng.integers(0, 256, size=(210, 160, 3), dtype=np.uint8)
    ours = gaussian_blur(frame, radius).astype(int)
    size = 2 * radius + 1
    theirs = cv2.GaussianBlur(frame, (size, size), radius / 2.0).astype(int)
    assert np.abs(ours - theirs).max() <= 2
    assert np.abs(ours - frame).mean() > 10  # it does blur
    assert np.array_equal(gaussian_blur(frame, 0), frame)


def test_compose_is_the_masked_sum():
    rng = np.random.default_rng(3)
    frame = rng.integers(0, 256, size=(8, 9, 3), dtype=np.uint8)
    outside = rng.integers(0, 256, size=(8, 9, 3), dtype=np.uint8)
    mask = (rng.random((8, 9)) > 0.5).astype(np.uint8)
    expected = mask[:, :, None] * frame + (1 - mask[:, :, None]) * outside
    assert np.array_equal(compose(frame, mask, outside), expected)


# Timing ---------------------------------------------------------------------------------------

def _released(result):
    return [r.item for r in result[1]] if isinstance(result, tuple) else [r.item for r in result]


def test_an_utterance_is_valid_from_its_stamp_for_the_ttl():
    timeline = Timeline(ttl_ns=10 * S)
    assert timeline.add_observation(1 * S, 'o1') == []  # nothing said yet: held
    assert _released(timeline.add_utterance('ladder', 2 * S)) == []  # o1 is older
    assert _released(timeline.add_observation(2 * S, 'o2')) == ['o2']
    assert _released(timeline.add_observation(11 * S, 'o11')) == ['o11']
    assert timeline.add_observation(12 * S, 'o12') == []  # 2 s + 10 s: expired
    _, newer = timeline.add_utterance('skull', 5 * S)  # covers 5..15 s: releases o12
    assert [(r.item, r.utterance.text) for r in newer] == [('o12', 'skull')]
    assert timeline.valid_at(6 * S).text == 'skull'  # the newest at or before wins
    assert timeline.valid_at(4 * S).text == 'ladder'


def test_a_late_stamped_utterance_releases_the_observations_it_covers_once():
    timeline = Timeline(ttl_ns=1 * S)
    for t in (10, 11, 12, 13):
        assert timeline.add_observation(t * S // 10, f'o{t}') == []
    assert _released(timeline.add_utterance('rope', 11 * S // 10)) == ['o11', 'o12', 'o13']
    assert timeline.held == 1  # o10 predates it
    assert _released(timeline.add_utterance('rope again', 11 * S // 10)) == []  # not twice


def test_plain_utterances_are_stamped_with_the_newest_observation():
    timeline = Timeline(ttl_ns=10 * S)
    early, released = timeline.add_utterance('spoken before any frame')
    assert early.stamp_ns is None and released == []
    released = timeline.add_observation(100 * S, 'first')
    assert [(r.item, r.utterance.stamp_ns) for r in released] == [('first', 100 * S)]
    timeline.add_observation(200 * S, 'later')  # held: the first utterance expired
    now, released = timeline.add_utterance('now')
    assert now.stamp_ns == 200 * S
    assert [(r.item, r.utterance.text) for r in released] == [('later', 'now')]


def test_a_withdrawn_copy_no_longer_counts():
    timeline = Timeline(ttl_ns=10 * S)
    timeline.add_observation(50 * S, 'o50')
    copy, _ = timeline.add_utterance('jump')  # the plain copy came first, stamped now
    original, _ = timeline.add_utterance('jump', 49 * S)
    timeline.discard(copy)
    assert timeline.valid_at(55 * S) is original
    fresh = Timeline(ttl_ns=S)
    early, _ = fresh.add_utterance('before any frame')
    fresh.add_observation(3 * S, 'o3')  # stamps it
    fresh.discard(early)
    assert fresh.valid_at(3 * S) is None


def test_held_observations_are_bounded_and_counted():
    timeline = Timeline(ttl_ns=S, capacity=3)
    for t in range(5):
        timeline.add_observation(t * S, t)
    assert timeline.held == 3 and timeline.dropped == 2
    assert _released(timeline.add_utterance('x', 0)) == []  # 0 and 1 are gone
    assert timeline.clear_held() == 3


def test_without_require_utterance_every_observation_is_released():
    timeline = Timeline(ttl_ns=S, require_utterance=False)
    first = timeline.add_observation(5 * S, 'a')
    assert [(r.item, r.utterance) for r in first] == [('a', None)]
    timeline.add_utterance('key', 5 * S)
    assert timeline.add_observation(5 * S + 1, 'b')[0].utterance.text == 'key'


# Manifest -------------------------------------------------------------------------------------

def test_parse_route():
    assert parse_route('NOOP*2 down  FIRE*1') == ('NOOP', 'NOOP', 'DOWN', 'FIRE')
    with pytest.raises(ManifestError):
        parse_route('NOOP*x')


def test_packaged_manifest_names_one_agent_and_loads_every_template():
    manifest = load_manifest()
    assert manifest.agent.name == 'agent' and manifest.agent.moves
    images = load_template_images(manifest)
    for spec in manifest.objects:
        assert len(images[spec.name]) == len(spec.templates)
        for image in images[spec.name]:
            assert image.ndim == 3 and image.dtype == np.uint8


def test_a_missing_template_file_is_named(tmp_path):
    folder = Path(load_manifest().folder)
    shutil.copytree(folder, tmp_path / 'templates')
    (tmp_path / 'templates' / 'key.png').unlink()
    manifest = load_manifest(tmp_path / 'templates' / 'manifest.yaml')
    with pytest.raises(TemplateFileError, match='key.png'):
        load_template_images(manifest)


def test_a_broken_manifest_says_what_is_wrong(tmp_path):
    path = tmp_path / 'manifest.yaml'
    path.write_text('emulator: {env_id: X}\nobjects: {a: {templates: []}}\n')
    with pytest.raises(ManifestError, match='no templates'):
        load_manifest(path)
    with pytest.raises(TemplateFileError, match='nowhere.yaml'):
        load_manifest(tmp_path / 'nowhere.yaml')


# Parameters -----------------------------------------------------------------------------------

def test_default_settings():
    settings = Settings.from_values({})
    assert settings.saliency == SaliencyConfig('language', 3, 0.0, 0.3)
    assert settings.saliency.sigma == 1.5
    assert settings.ttl_ns == 10 * S and settings.require_utterance
    assert settings.method == cv2.TM_CCORR_NORMED


def test_every_parameter_is_documented_and_other_names_are_not_ours():
    docs = field_docs(Settings)
    assert all(docs.get(f.name) for f in fields(Settings))
    assert Settings.from_values({'use_sim_time': True}) == Settings()


@pytest.mark.parametrize('values, check', [
    ({'mode': False}, lambda s: s.saliency.mode == 'off'),  # `-p mode:=off` is YAML false
    ({'utterance_ttl': 5}, lambda s: s.ttl_ns == 5 * S),  # an integer for a float
    ({'blur_radius': 2.0}, lambda s: s.saliency.blur_radius == 2),
    ({'match_method': 'TM_SQDIFF_NORMED'}, lambda s: s.method == cv2.TM_SQDIFF_NORMED),
    ({'require_utterance': False}, lambda s: not s.require_utterance),
])
def test_settings_accept(values, check):
    assert check(Settings.from_values(values))


@pytest.mark.parametrize('values, message', [
    ({'mode': 'loud'}, 'mode'), ({'mode': True}, 'mode'), ({'utterance_ttl': 0.0}, 'positive'),
    ({'utterance_ttl': 'soon'}, 'utterance_ttl'), ({'blur_radius': 2.5}, 'whole'),
    ({'blur_radius': -1}, 'at least'), ({'fade': 2.0}, 'fade'),
    ({'match_method': 'TM_CCORR'}, 'TM_CCORR_NORMED'), ({'require_utterance': 'yes'}, 'true'),
    ({'observation_buffer': 0}, 'observation_buffer'),
])
def test_settings_reject_with_the_reason(values, message):
    with pytest.raises(ValueError, match=message):
        Settings.from_values(values)
