"""
Render the saliency node's DoorKey templates: one PNG per cell look the manifest lists.

A template is one cell of the agent's view as MiniGrid draws it (``gridworld.observe``:
``Grid.render`` of the 7 x 7 cells ahead, ``TILE_SIZE`` pixels each, the cells the agent can
see highlighted; hidden ones are drawn empty), the same pixels wherever the cell is: what the
cell holds (``cell``: 'yellow key', 'blue door open', 'goal', 'floor') and, with ``agent_dir``,
the agent on it (always facing up in its own view, over what it carries). A template's
``backdrop`` is its cell without its object: the agent's without the agent, any other's the
empty floor (with the agent on it if the template has it). Deterministic: no randomness, no
level generator.

    doorkey_make_templates            # rewrite the PNGs next to the manifest
    doorkey_make_templates --check    # exit 1 if a PNG differs from a fresh render, or a look
                                      # a DoorKey frame can show has no template
"""

import argparse
from pathlib import Path
import sys
from typing import Dict, Iterator, Optional, Tuple

from attention_tasks.gridworld import TILE_SIZE
import cv2
from minigrid.core.constants import COLOR_NAMES
from minigrid.core.grid import Grid
from minigrid.core.world_object import Ball, Box, Door, Goal, Key, WorldObj
import numpy as np
import yaml

SOURCE = 'minigrid'
"""The manifest's ``source`` this tool renders."""
AGENT_DIRS = ('right', 'down', 'left', 'up')
"""``agent_dir`` names, in MiniGrid's direction order (0 right .. 3 up)."""
VIEW_DIR = 'up'
"""The agent's direction in its own view."""
KINDS = {'key': Key, 'ball': Ball, 'box': Box}
DOOR_STATES = ('locked', 'closed', 'open')
AGENT_ON = ('floor',) + tuple(f'{c} {kind}' for c in COLOR_NAMES for kind in KINDS)
"""What the agent's cell shows under it in its view: nothing, or what it carries (MiniGrid
draws neither the open door nor the goal it stands on there)."""

Look = Tuple[str, Optional[str]]
"""``(cell, agent_dir)``: what a template shows; agent_dir None: no agent."""


def manifest_path() -> Path:
    """Return the DoorKey task's manifest (``Task.manifest``)."""
    from attention_tasks.doorkey.task import TASK
    return TASK.manifest


def cell_object(cell: str) -> Optional[WorldObj]:
    """'yellow key' -> Key('yellow'); 'blue door open'; 'goal'; 'floor' -> None."""
    words = cell.split()
    if words == ['floor']:
        return None
    if words == ['goal']:
        return Goal()
    if len(words) == 2 and words[0] in COLOR_NAMES and words[1] in KINDS:
        return KINDS[words[1]](words[0])
    if (len(words) == 3 and words[0] in COLOR_NAMES and words[1] == 'door'
            and words[2] in DOOR_STATES):
        return Door(words[0], is_open=words[2] == 'open', is_locked=words[2] == 'locked')
    raise ValueError(f'cell {cell!r} is not floor, goal, "<colour> key|ball|box" or '
                     f'"<colour> door locked|closed|open" (colours: {", ".join(COLOR_NAMES)})')


def render_look(look: Look, tile_size: int) -> np.ndarray:
    """Return the RGB pixels of one cell the agent sees as ``Grid.render`` draws it."""
    cell, agent_dir = look
    if agent_dir is not None and agent_dir not in AGENT_DIRS:
        raise ValueError(f'agent_dir {agent_dir!r} is not one of {", ".join(AGENT_DIRS)}')
    if agent_dir is not None and cell not in AGENT_ON:
        raise ValueError(f"the agent's cell never shows {cell!r}")
    grid = Grid(3, 3)
    grid.set(1, 1, cell_object(cell))
    agent = (1, 1) if agent_dir is not None else (-1, -1)
    direction = AGENT_DIRS.index(agent_dir) if agent_dir is not None else None
    frame = grid.render(tile_size, agent, direction, highlight_mask=np.ones((3, 3), bool))
    return frame[tile_size:2 * tile_size, tile_size:2 * tile_size].copy()


def frame_looks() -> Iterator[Look]:
    """Yield every look a cell of a DoorKey frame can have, walls and empty floor aside."""
    for color in COLOR_NAMES:
        for kind in KINDS:
            yield f'{color} {kind}', None
        for state in DOOR_STATES:
            yield f'{color} door {state}', None
    yield 'goal', None
    for cell in AGENT_ON:
        yield cell, VIEW_DIR


def backdrop_look(look: Look, agent: bool) -> Look:
    """Return what a template's cell shows without its object: the agent, or another one."""
    cell, agent_dir = look
    return (cell, None) if agent else ('floor', agent_dir)


def wanted_files(raw: dict) -> Dict[str, Look]:
    """Every PNG the manifest names (templates and backdrops), with the look it shows."""
    if raw.get('source') != SOURCE:
        raise ValueError(f'manifest source is {raw.get("source")!r}, not {SOURCE!r}')
    files: Dict[str, Look] = {}

    def want(file: str, look: Look) -> None:
        if files.setdefault(file, look) != look:
            raise ValueError(f'{file} is named for two looks: {files[file]} and {look}')

    defaults = raw.get('defaults') or {}
    for spec in raw['objects'].values():
        spec = {**defaults, **spec}
        for template in spec['templates']:
            look = (str(template['cell']), template.get('agent_dir'))
            want(str(template['file']), look)
            backdrop = template.get('backdrop', spec.get('backdrop'))
            if backdrop:
                want(str(backdrop), backdrop_look(look, bool(spec.get('agent'))))
    return files


def missing_looks(raw: dict):
    """Return the looks a frame can show that no template of the manifest shows."""
    shown = {(str(t['cell']), t.get('agent_dir'))
             for spec in raw['objects'].values() for t in spec['templates']}
    return [look for look in frame_looks() if look not in shown]


def render_all(raw: dict, tile_size: int) -> Dict[str, np.ndarray]:
    """Every PNG of the manifest, by file name, as RGB."""
    return {file: render_look(look, tile_size) for file, look in wanted_files(raw).items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[1])
    parser.add_argument('--manifest', help="manifest YAML (default: the DoorKey task's)")
    parser.add_argument('--out', help='folder for the PNGs (default: the manifest folder)')
    parser.add_argument('--check', action='store_true',
                        help='compare with the existing PNGs instead of writing')
    args = parser.parse_args(argv)
    path = Path(args.manifest) if args.manifest else manifest_path()
    raw = yaml.safe_load(path.read_text())
    out = Path(args.out) if args.out else path.parent
    out.mkdir(parents=True, exist_ok=True)
    problems = [f'no template shows {cell}' + (f' with the agent facing {d}' if d else '')
                for cell, d in missing_looks(raw)]
    rendered = render_all(raw, TILE_SIZE)
    for file, rgb in rendered.items():
        target = out / file
        if args.check:
            existing = cv2.imread(str(target), cv2.IMREAD_COLOR)
            if existing is None or not np.array_equal(existing[:, :, ::-1], rgb):
                problems.append(f'{file} differs from a fresh render')
        else:
            cv2.imwrite(str(target), np.ascontiguousarray(rgb[:, :, ::-1]))
    if not args.check:
        print(f'{len(rendered)} PNGs written to {out}')
    for problem in problems:
        print(problem, file=sys.stderr)
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main())
