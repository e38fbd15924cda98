"""
The session layout in Lichtblick's format. Pure.

foxglove-sdk writes Foxglove's layout format (``version`` 1: a tree of splits, tabs and panels).
Lichtblick, Foxglove Studio's open-source fork, imports the format Studio had before: every
panel's config under ``configById`` (ids ``Type!name``), the arrangement as a binary mosaic
(``first``, ``second``, ``direction``, ``splitPercentage``), tabs as ``Tab`` panels holding
mosaics of their own, and ``globalVariables``, ``userNodes`` and ``playbackConfig`` beside
them (Lichtblick refuses a file without those). The panels' own configs are the same in both.
"""

import re
from typing import Dict, Union

Mosaic = Union[str, dict]
TITLE_KEYS = ('lichtblickPanelTitle', 'foxglovePanelTitle')
"""Where Lichtblick (and Studio before it) keep a panel's title in its config."""


def _slug(title: str) -> str:
    return re.sub(r'[^a-z0-9]+', '_', title.lower()).strip('_') or 'panel'


class _Converter:
    def __init__(self):
        self.config_by_id: Dict[str, dict] = {}

    def _id(self, panel_type: str, title: str) -> str:
        base = f'{panel_type}!{_slug(title)}'
        panel_id, n = base, 1
        while panel_id in self.config_by_id:
            n += 1
            panel_id = f'{base}_{n}'
        return panel_id

    def node(self, content: dict) -> Mosaic:
        kind = content['type']
        if kind == 'split':
            return self._split(content['direction'], content['items'])
        if kind == 'tabs':
            return self._tabs(content)
        if kind == 'panel':
            return self._panel(content)
        raise ValueError(f'a layout node of type {kind!r} has no Lichtblick form')

    def _split(self, direction: str, items: list) -> Mosaic:
        if not items:
            raise ValueError('a split with no items')
        if len(items) == 1:
            return self.node(items[0]['content'])
        first, rest = items[0], items[1:]
        total = sum(item.get('proportion', 1) for item in items)
        return {'first': self.node(first['content']),
                'second': self._split(direction, rest),
                'direction': direction,
                'splitPercentage': round(100.0 * first.get('proportion', 1) / total, 3)}

    def _tabs(self, content: dict) -> str:
        tabs = [{'title': tab['title'], 'layout': self.node(tab['content'])}
                for tab in content['tabs']]
        panel_id = self._id('Tab', '_'.join(tab['title'] for tab in tabs))
        self.config_by_id[panel_id] = {'activeTabIdx': content.get('selectedTabIndex', 0),
                                       'tabs': tabs}
        return panel_id

    def _panel(self, content: dict) -> str:
        title = content.get('title') or content['panelType']
        config = dict(content.get('config', {}))
        if content['panelType'] == 'Plot':  # Lichtblick draws a series only when enabled
            config['paths'] = [{'enabled': True, **path} for path in config.get('paths', [])]
        for key in TITLE_KEYS:
            config[key] = title
        panel_id = self._id(content['panelType'], title)
        self.config_by_id[panel_id] = config
        return panel_id


def to_lichtblick(layout: dict) -> dict:
    """Return Lichtblick's layout for foxglove-sdk's ``layout`` (its JSON as a dict)."""
    if layout.get('version') != 1 or 'content' not in layout:
        raise ValueError('not a foxglove-sdk layout (version 1 with content)')
    converter = _Converter()
    mosaic = converter.node(layout['content'])
    return {'configById': converter.config_by_id, 'globalVariables': {}, 'userNodes': {},
            'playbackConfig': {'speed': 1.0}, 'layout': mosaic}
