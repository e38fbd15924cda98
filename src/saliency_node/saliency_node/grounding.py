"""
Ground an utterance: find the template objects its words name (no rclpy).

Words are lower-cased, split on anything that is not a letter, and reduced to a crude stem
(plural and verb endings dropped: "Climb downs the ladders!" -> climb, down, the, ladder) on both
sides, the utterance and the manifest's words, so "gates" finds an object listing "gate".
Unknown words are ignored. Two-word phrases in the manifest ("bad guy") match adjacent words.
The agent is always selected.
"""

import re
from typing import Dict, Iterable, List, NamedTuple, Sequence, Tuple
import unicodedata

_WORD = re.compile(r'[a-z]+')


def ascii_text(text: str) -> str:
    """Fold accents (NFKD) and drop any other non-ASCII character."""
    folded = unicodedata.normalize('NFKD', text)
    return folded.encode('ascii', 'ignore').decode('ascii')


def stem(word: str) -> str:
    """Return a crude, consistent stem: enough to equate plurals and verb forms."""
    w = word.lower()
    if len(w) > 4 and w.endswith('ies'):
        return w[:-3] + 'y'                       # enemies -> enemy
    if len(w) > 4 and w.endswith(('sses', 'ches', 'shes', 'xes', 'zes')):
        return w[:-2]                             # boxes -> box
    if len(w) > 3 and w.endswith('s') and not w.endswith(('ss', 'us', 'is')):
        w = w[:-1]                                # ladders -> ladder, downs -> down
    if len(w) > 5 and w.endswith('ing'):
        return w[:-3]                             # climbing -> climb
    if len(w) > 4 and w.endswith('ed'):
        return w[:-2]                             # climbed -> climb
    return w


def tokenize(text: str) -> List[str]:
    """Stems of the words of ``text``, in order."""
    return [stem(word) for word in _WORD.findall(ascii_text(text).lower())]


class Grounding(NamedTuple):
    """What an utterance names."""

    objects: Tuple[str, ...]
    """Selected object names (manifest order), the agent always among them."""
    named: Tuple[str, ...]
    """Objects the words named (may be empty: then only the agent is selected)."""


class Grounder:
    """Maps utterances to manifest objects by their names and listed words."""

    def __init__(self, vocabulary: Dict[str, Sequence[str]], agent: str):
        """``vocabulary``: object name -> words that refer to it; ``agent``: the agent's name."""
        self.agent = agent
        self.order = list(vocabulary)
        self._phrases: Dict[Tuple[str, ...], set] = {}
        for name, words in vocabulary.items():
            for phrase in [name, *words]:
                key = tuple(tokenize(phrase))
                if key:
                    self._phrases.setdefault(key, set()).add(name)
        self._longest = max((len(k) for k in self._phrases), default=1)

    @classmethod
    def from_manifest(cls, manifest) -> 'Grounder':
        return cls({spec.name: spec.words for spec in manifest.objects}, manifest.agent.name)

    def _named(self, stems: Sequence[str]) -> Iterable[str]:
        for start in range(len(stems)):
            for length in range(1, self._longest + 1):
                yield from self._phrases.get(tuple(stems[start:start + length]), ())

    def ground(self, utterance: str) -> Grounding:
        stems = tokenize(utterance)
        named = set(self._named(stems))
        selected = named | {self.agent}
        return Grounding(objects=tuple(n for n in self.order if n in selected),
                         named=tuple(n for n in self.order if n in named))
