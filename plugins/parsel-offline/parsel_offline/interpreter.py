"""A deterministic, rule-based reading of common edit requests.

The interpreter reads the request and the shape *as the prompt gives them* (the
``<shape>`` description, read back with :func:`parsel_core.language.read_description`),
so it knows what a hosted model would know and nothing more. It splits the request
into clauses, finds in each the edit words (``wider``, ``tilt``, ``more``), the parts
meant (labels, synonyms, position words such as ``front`` or ``top``) and direction
words, and turns them into:

* the seed edit: the first clause that asks for a change;
* type hints from the other clauses that say how attached parts should follow (``by
  tilting the legs`` -> rotate, ``keep the back fixed`` -> keep); a further clause about
  parts not attached to the first one's (``and tilt the back``), or a count change
  (``and add more slats``), is an edit of its own and joins the seed;
* the symmetry relations the request breaks: those that a position word splits
  (``the front legs`` splits the front legs from the back ones), mirrors across the same
  plane between parts carried by the split ones (the handle on the left door), and
  mirrors across the direction mirrored parts are all moved or tilted (``tilt the legs
  forward``).

Any word it cannot place makes it raise :class:`NotUnderstood` with the reason; it never
guesses.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from parsel_core.language.describe import PartSummary, ShapeSummary
from parsel_offline import lexicon as lx
from parsel_offline.lexicon import Intent

AXIS_WORDS = ("x", "y", "z")
#: World direction word -> (axis, sign).
WORLD = {"right": (0, 1), "left": (0, -1), "up": (1, 1), "down": (1, -1), "front": (2, 1), "back": (2, -1)}
#: (axis, sign) -> the face word of that side.
SIDE = {(0, 1): "right", (0, -1): "left", (1, 1): "top", (1, -1): "bottom", (2, 1): "front", (2, -1): "back"}
HINT_OF = {"size": "scale", "thickness": "scale", "uniform": "scale", "taper": "scale", "move": "translate",
           "spread": "translate", "tilt": "rotate", "rotate": "rotate", "open": "rotate", "keep": "keep"}
TILT_AMOUNT = "0.3 * x"
ROTATE_AMOUNT = "pi / 4 * x"
OPEN_AMOUNT = "pi / 2 * x"
GROW, SHRINK = "x", "-0.5 * x"


class NotUnderstood(Exception):
    """The request (or a clause of it) is outside what the interpreter knows; the message says why."""


def _axis_word(axis: int, sign: int = 1) -> str:
    return ("" if sign > 0 else "-") + AXIS_WORDS[axis]


def _amount(value: float) -> str:
    text = f"{value:.3g}"
    return f"{text} * x"


@dataclass(frozen=True)
class Origin:
    """Where an op's origin comes from: a part's centre, one of its features, or a point."""

    kind: str  # "center" | "face" | "edge" | "point"
    part: str | None = None
    words: tuple[str, ...] = ()
    point: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class SeedOp:
    """An edit in the reply API's terms (part ids, face words, direction words)."""

    op: str
    target: str
    amount: str
    feature: tuple[str, ...] = ()
    origin: Origin | None = None
    dirs: tuple[tuple[str, str], ...] = ()
    mode: str | None = None
    group: bool = False

    @property
    def signature(self) -> tuple[str, str]:
        return self.op, self.target


@dataclass
class Mention:
    """Parts a clause names: a label (maybe narrowed by position words), the whole object, or the rest."""

    parts: tuple[str, ...]
    start: int
    end: int
    words: tuple[str, ...]
    labels: tuple[str, ...] = ()
    whole: bool = False
    others: bool = False
    qualifiers: tuple[tuple[str, ...], ...] = ()
    pronoun: bool = False

    @property
    def qualified(self) -> bool:
        return bool(self.qualifiers)

    @property
    def text(self) -> str:
        return " ".join(self.words)


@dataclass
class Clause:
    text: str
    connector: str | None
    intents: list[Intent]
    mentions: list[Mention]
    directions: list[str]
    number: int | None = None
    #: How far the edit goes: ("small"|"large", None), ("percent", p), ("factor", f), ("degrees", d).
    degree: tuple[str, float | None] | None = None
    #: A world axis a span phrase names (``from front to back``: z).
    span_axis: int | None = None


@dataclass
class Interpretation:
    """The reading of one request: seed ops, hints, broken relations and the reasoning in words."""

    request: str
    ops: list[SeedOp] = field(default_factory=list)
    hints: dict[str, str] = field(default_factory=dict)
    hint_keys: dict[str, str] = field(default_factory=dict)
    breaks: list[str] = field(default_factory=list)
    reasons: list[str] = field(default_factory=list)
    break_reasons: dict[str, str] = field(default_factory=dict)
    hint_reasons: list[str] = field(default_factory=list)


class Interpreter:
    """Reads requests about one shape (as summarised from the prompt)."""

    def __init__(self, shape: ShapeSummary) -> None:
        self.shape = shape
        self.labels = shape.labels()
        self.category = self._category()
        self.size = max(shape.size, 1e-9)
        self.extent = shape.hi - shape.lo
        self.centre = shape.centre
        self.phrases = self._phrases()
        #: Symmetry relations the request being read breaks (they no longer tie parts together).
        self.broken: set[str] = set()
        #: Words that ask for a plugin's operator (``twist``), from the operators' ``words`` attribute.
        self.plugin_words = plugin_words()
        self._vocabulary: frozenset[str] | None = None
        #: Messages about clauses of unknown words that named no part and no edit (left out).
        self.chatter: list[str] = []
        #: Parts the request says to keep, which a whole-object edit does not pick as its seed.
        self.kept: set[str] = set()
        #: Parts an edit implies stay still (the frame a door opens from), with the reason: ``keep`` hints.
        self.held: dict[str, str] = {}

    # -- vocabulary of this shape ---------------------------------------------------------

    def _category(self) -> tuple[str, ...]:
        name = self.shape.name.lower()
        pieces = [lx.singular(w) for w in re.split(r"[^a-z]+", name) if w]
        for words in lx.CATEGORIES.values():
            if name in words or any(piece in words for piece in pieces):
                return words
        return (name,) if name.isalpha() else ()

    def _labels_for(self, target: str) -> tuple[str, ...]:
        """Existing labels a synonym target names: the label itself, or labels ending with that word."""
        if target in self.labels:
            return (target,)
        found = tuple(sorted(label for label in self.labels if label.split("_")[-1] == target))
        if found:
            return found
        if target == "back":
            return tuple(sorted(label for label in self.labels if label.split("_")[0] == "back"))
        return ()

    def _phrases(self) -> dict[tuple[str, ...], tuple[str, ...]]:
        phrases: dict[tuple[str, ...], set[str]] = {}

        def add(words: tuple[str, ...], labels: Sequence[str]) -> None:
            if labels:
                phrases.setdefault(words, set()).update(labels)

        for label in self.labels:
            words = tuple(lx.singular(w) for w in label.lower().replace("-", "_").split("_") if w)
            add(words, [label])
            if len(words) > 1:
                add(words[-1:], [label])
        for words, targets in lx.PHRASES.items():
            add(words, [label for t in targets for label in self._labels_for(t)])
        for word, targets in lx.SYNONYMS.items():
            if (word,) in phrases:
                continue
            for target in targets:
                labels = self._labels_for(target)
                if labels:
                    add((word,), labels)
                    break
        return {k: tuple(sorted(v)) for k, v in phrases.items()}

    # -- geometry --------------------------------------------------------------------------

    def part(self, pid: str) -> PartSummary:
        return self.shape.parts[pid]

    def main_part(self) -> str:
        """The part the object is built around: a core label, else the most attached part."""
        for label in lx.CORE_LABELS:
            if label in self.labels and len(self.labels[label]) == 1:
                return self.labels[label][0]

        def attachments(pid: str) -> int:
            return sum(1 for r in self.shape.relations_of(pid) if r.kind == "attachment")

        return max(self.shape.parts, key=lambda p: (attachments(p), float(np.prod(self.part(p).size)), p))

    def supports(self) -> tuple[str, ...]:
        return tuple(pid for label in lx.SUPPORT_LABELS for pid in self.labels.get(label, ()))

    def group_of(self, parts: Sequence[str]):
        """The translation or rotation group all of ``parts`` belong to, if any."""
        for relation in self.shape.groups():
            if set(parts) <= set(relation.members):
                return relation
        return None

    def components(self, parts: Sequence[str]) -> list[tuple[str, ...]]:
        """``parts`` split into sets joined by symmetry relations lying wholly inside ``parts``.

        A request names a handful of parts, so the sets are merged relation by relation
        (each part always maps to its whole set so far) rather than through networkx, whose
        import (about 0.2 s of CPU) would cost more than the rest of the request."""
        inside = set(parts)
        component = {p: frozenset((p,)) for p in parts}
        for relation in self.shape.relations.values():
            if relation.kind in ("reflection", "translation", "rotation") and set(relation.members) <= inside \
                    and relation.id not in self.broken:
                merged = frozenset().union(*(component[m] for m in relation.members))
                component.update(dict.fromkeys(merged, merged))
        return sorted({tuple(sorted(c)) for c in component.values()})

    def bounds(self, parts: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
        return (np.min([self.part(p).lo for p in parts], axis=0), np.max([self.part(p).hi for p in parts], axis=0))

    @staticmethod
    def _longest(size: Sequence[float]) -> int:
        return int(np.argmax(np.asarray(size)))

    # -- reading ---------------------------------------------------------------------------

    def interpret(self, request: str) -> Interpretation:
        words = lx.rewrite(lx.tokens(request))
        if not any(w != "," for w in words):
            raise NotUnderstood("the request is empty")
        words, corrections = self.correct(words)
        words = self.drop_purpose(words)
        clauses = self.resolve([c for c in (self.clause(tokens, connector) for tokens, connector in self.split(words))
                                if c])
        primary_index = next((i for i, c in enumerate(clauses) if any(it.action != "keep" for it in c.intents)),
                             None)
        if primary_index is None:
            if self.chatter:
                raise NotUnderstood(self.chatter[0])
            raise NotUnderstood(f"'{request}' says what to keep but not what to change")
        primary = clauses[primary_index]
        self.kept = {p for c in clauses if c is not primary and all(it.action == "keep" for it in c.intents)
                     for m in c.mentions if not m.whole for p in m.parts}
        self.held = {}
        out = Interpretation(request)
        out.reasons.extend(f"I read '{wrong}' as '{right}'." for wrong, right in corrections)
        self.find_breaks(clauses, out)
        out.ops.extend(self.seed_ops(primary, out.reasons))
        primary_parts = {p for m in primary.mentions for p in m.parts}
        for clause in clauses:
            if clause is primary:
                continue
            if self.independent(clause, primary):
                out.ops.extend(self.seed_ops(clause, out.reasons))
            else:
                self.secondary(clause, primary_parts, out)
        seeded = {op.target for op in out.ops}
        for part, reason in self.held.items():
            if part not in out.hints and part not in seeded:
                out.hints[part] = out.hint_keys[part] = "keep"
                out.hint_reasons.append(reason)
        out.ops = list(dict.fromkeys(out.ops))  # the same edit asked twice is one edit, not two compounding
        return out

    # -- words before clauses ---------------------------------------------------------------

    def _known(self, word: str) -> bool:
        if word in self.vocabulary or lx.is_number(word) or not word.isalpha():
            return True
        return lx.singular(word) in self.vocabulary or lx.lemma(word) in self.vocabulary or \
            _base_verb(word) in self.vocabulary

    @property
    def vocabulary(self) -> frozenset[str]:
        if self._vocabulary is None:
            words = set(lx.FILLERS) | set(lx.INTENTS) | set(lx.CHANGE_VERBS) | set(lx.POSITIONAL_COMPARATIVES) \
                | set(lx.COUNT_WORDS) | set(lx.ADJECTIVES) | set(lx.EXTRA_COMPARATIVES) | set(lx.DIMENSION_NOUNS) \
                | set(lx.DIRECTIONS) | set(lx.QUALIFIERS) | set(lx.NUMBER_WORDS) | set(lx.WHOLE_WORDS) \
                | set(lx.OTHERS_WORDS) | set(lx.NEGATIONS) | set(lx.PLAIN_VERBS) | set(lx.SMALL_DEGREE) \
                | set(lx.LARGE_DEGREE) | set(lx.FACTORS) | set(lx.CLAUSE_BREAKS) | set(lx.CLAUSE_STARTERS) \
                | set(lx.PRONOUNS) | set(lx.PART_NOUNS) | set(lx.DETERMINERS) | set(self.plugin_words) \
                | {w for words in lx.CATEGORIES.values() for w in words} | {"and", "or", "as", "to", "enough"}
            words |= {w for key in self.phrases for w in key} | set(self.category)
            self._vocabulary = frozenset(words)
        return self._vocabulary

    def _targets(self) -> dict[str, str]:
        """Words a typo may stand for: this shape's part words (and plurals), its category, edit words."""
        targets: dict[str, str] = {}
        for key in self.phrases:
            for word in key:
                targets.setdefault(word, word)
                targets.setdefault(word + "s", word + "s")
        for word in (*self.category, *lx.INTENTS, *lx.POSITIONAL_COMPARATIVES, *lx.ADJECTIVES,
                     *lx.EXTRA_COMPARATIVES, *lx.DIMENSION_NOUNS, *lx.DIRECTIONS, *lx.QUALIFIERS, *self.plugin_words):
            targets.setdefault(word, word)
        targets.update({"shelves": "shelves"} if "shelf" in targets else {})
        return targets

    def correct(self, words: list[str]) -> tuple[list[str], list[tuple[str, str]]]:
        """Misspelt words read as the one word of this shape's vocabulary they are one edit away from
        (two for words of six letters or more; a swap of neighbours is one edit), starting with the
        same letter; a word with no such unique match is left for the refusal to name."""
        out, corrections = [], []
        targets = None
        for word in words:
            if len(word) < 3 or self._known(word):
                out.append(word)
                continue
            if targets is None:  # (the first unknown word: most requests have none)
                from rapidfuzz.distance import DamerauLevenshtein

                targets = self._targets()
            limit = 1 if len(word) <= 5 else 2
            best: list[tuple[int, str]] = []
            for target in targets:
                if target[0] != word[0] or abs(len(target) - len(word)) > limit:
                    continue
                distance = DamerauLevenshtein.distance(word, target, score_cutoff=limit)
                if distance <= limit:
                    best.append((distance, target))
            # Ties go to words at least as long as the typo (a dropped letter is the commonest slip:
            # "longr" is "longer", not "long").
            best.sort(key=lambda item: (item[0], len(item[1]) < len(word), abs(len(item[1]) - len(word))))
            if best and (len(best) == 1 or best[0][0] < best[1][0]
                         or (len(best[0][1]) >= len(word)) != (len(best[1][1]) >= len(word))
                         or abs(len(best[0][1]) - len(word)) < abs(len(best[1][1]) - len(word))):
                out.append(best[0][1])
                corrections.append((word, best[0][1]))
            else:
                out.append(word)
        return out, corrections

    def drop_purpose(self, words: list[str]) -> list[str]:
        """``for my kids``, ``for the kitchen``, ``in my room``: who or where the edit is for says
        nothing about the edit, when the words after the preposition are not the shape's."""
        out: list[str] = []
        i = 0
        while i < len(words):
            if words[i] in ("for", "in", "at", "to") and i + 1 < len(words):
                k = i + 1
                while k < len(words) and words[k] in lx.DETERMINERS:
                    k += 1
                end = k
                while end < len(words) and words[end] != "," and not self._known(words[end]):
                    end += 1
                owned = words[i] == "for" or (k > i + 1 and words[i + 1] in ("my", "our", "your", "their"))
                if end > k and owned:
                    i = end
                    continue
            out.append(words[i])
            i += 1
        return out

    def resolve(self, clauses: list[Clause]) -> list[Clause]:
        """Topics and pronouns: ``the seat, make it deeper`` edits the seat; a clause that only names
        parts lends them to the next one; a clause with an edit and no part (``longer and taller``)
        edits the parts of the clause before it; an object word next to a part word (``the chair
        legs``) is the part's, not an edit of the whole object."""
        out: list[Clause] = []
        antecedent: list[Mention] = []
        for clause in clauses:
            parts = [m for m in clause.mentions if not m.whole and not m.others]
            pronouns = [m for m in clause.mentions if m.pronoun]
            if parts:
                clause.mentions = [m for m in clause.mentions if not m.whole]
            elif pronouns and antecedent:
                clause.mentions = [m for m in clause.mentions if not m.pronoun] + list(antecedent)
            elif not clause.mentions and antecedent and clause.intents:
                clause.mentions = list(antecedent)
            elif not clause.mentions and clause.intents and any(it.action != "keep" for it in clause.intents):
                if all(it.action in ("size", "uniform", "comparative", "move") for it in clause.intents):
                    clause.mentions = [Mention(tuple(self.shape.parts), 0, 0, ("it",), whole=True)]
                else:
                    raise NotUnderstood(f"'{clause.text}' does not say which part to edit")
            if any(not m.pronoun for m in clause.mentions):
                antecedent = [m for m in clause.mentions if not m.pronoun]
            if not clause.intents:
                continue  # a topic ("the seat, ..."): its parts go to the next clause
            self.settle(clause)
            out.append(clause)
        if not out and clauses:
            last = clauses[-1]
            raise NotUnderstood(f"'{last.text}' names {', '.join(m.text for m in last.mentions)} but no edit I "
                                "know (such as wider, longer, raise, tilt, taper, more, keep)")
        return out

    def independent(self, clause: Clause, primary: Clause) -> bool:
        """Whether a further clause is an edit of its own rather than how attached parts should follow.

        ``taper the legs and tilt the back`` asks for two edits; ``widen the seat and tilt the
        legs`` says how the legs (attached to the seat) should follow it; clauses opened by
        ``by``, ``with`` or ``while`` always say how.
        """
        if all(it.action == "keep" for it in clause.intents) or clause.connector not in (None, "and", "then"):
            return False
        if any(m.whole or m.others for m in primary.mentions + clause.mentions):
            return False
        mine = {p for m in clause.mentions for p in m.parts}
        theirs = {p for m in primary.mentions for p in m.parts}
        if mine & theirs:
            return False
        return not any(r.kind == "attachment" and (set(r.members) & mine) and (set(r.members) & theirs)
                       for r in self.shape.relations.values())

    @staticmethod
    def split(words: list[str]) -> list[tuple[list[str], str | None]]:
        """Clauses at commas and joining words; ``and`` splits only before a verb."""
        clauses: list[tuple[list[str], str | None]] = []
        current: list[str] = []
        connector: str | None = None
        for i, word in enumerate(words):
            nxt = words[i + 1] if i + 1 < len(words) else ""
            if word == "," or word in lx.CLAUSE_BREAKS or (word == "and" and lx.lemma(nxt) in lx.VERB_STARTS):
                if current:
                    clauses.append((current, connector))
                current, connector = [], (None if word == "," else word)
                continue
            if word in lx.CLAUSE_STARTERS and current:
                clauses.append((current, connector))
                current, connector = [], None
            current.append(word)
        if current:
            clauses.append((current, connector))
        return clauses

    def clause(self, words: list[str], connector: str | None) -> Clause | None:
        text = " ".join(words)
        used = [False] * len(words)
        span_axis = self.find_span(words, used)
        mentions = self.find_mentions(words, used)
        degree = self.find_degree(words, used)
        intents = self.find_intents(words, used, mentions)
        directions = []
        for i, word in enumerate(words):
            if not used[i] and word in lx.DIRECTIONS:
                directions.append(lx.DIRECTIONS[word])
                used[i] = True
        number = next((lx.NUMBER_WORDS[w] for w in reversed(words) if w in lx.NUMBER_WORDS), None)
        if number is None:
            number = next((int(w) for w in words if w.isdigit() and 0 < int(w) < 100), None)
        left = [w for i, w in enumerate(words) if not used[i] and w not in lx.FILLERS and not lx.is_number(w)
                and w not in lx.NUMBER_WORDS and w not in ("and", "or", "as", "enough") and w not in lx.DETERMINERS
                and w not in lx.PRONOUNS]
        missing = [w for w in left if lx.singular(w) in lx.PART_NOUNS]
        if missing:
            have = ", ".join(sorted(self.labels))
            raise NotUnderstood(f"the {self.shape.name} has no {missing[0]} (its parts are: {have})")
        if left:
            unknown = ", ".join(f"'{w}'" for w in dict.fromkeys(left))
            message = f"I do not understand {unknown} in '{text}'; {self.suggestion()}"
            if not intents and not mentions:
                self.chatter.append(message)
                return None  # chatter around the request ("hey", "my guests say"): no part, no edit
            raise NotUnderstood(message)
        if not intents and not mentions:
            return None
        return Clause(text, connector, intents, mentions, directions, number, degree, span_axis)

    def suggestion(self) -> str:
        """A phrasing this shape supports, for refusals."""
        label = max(self.labels, key=lambda name: (len(self.labels[name]), name))
        noun = label.replace("_", " ") + ("s" if len(self.labels[label]) > 1 else "")
        return f"try a phrasing such as 'make the {noun} longer' or 'move the {noun} up'"

    def settle(self, clause: Clause) -> None:
        """What depends on the whole clause: direction words, whole-object names, position words."""
        intents, directions = self.combine(clause.intents, clause.directions, clause.text)
        mentions = clause.mentions
        if any(it.action in ("count", "spread") for it in intents):
            # "add another shelf" on a shelf: the object's name is also the name of a part.
            for n, mention in enumerate(mentions):
                key = (lx.singular(mention.words[0]),) if mention.whole and len(mention.words) == 1 else None
                if key in self.phrases and mention.words[0] not in lx.WHOLE_WORDS:
                    labels = self.phrases[key]
                    mentions[n] = Mention(tuple(p for label in labels for p in self.labels[label]), mention.start,
                                          mention.end, mention.words, labels)
        # Position words left after a part noun ("the legs at the front") narrow that part.
        sides = [("top" if d == "up" else "bottom" if d == "down" else d) for d in directions]
        sides = [d for d in sides if d in ("left", "right", "top", "bottom", "front", "back")]
        if sides and all(it.action in ("size", "thickness", "uniform", "count", "keep") for it in intents):
            last = mentions[-1]
            if not last.whole and not last.others:
                mentions[-1] = self.qualify(last, [tuple(sides)])
                directions = []
        clause.intents, clause.directions, clause.mentions = intents, directions, mentions

    def find_span(self, words: list[str], used: list[bool]) -> int | None:
        """``from front to back``, ``left to right``: the world axis between two opposite sides."""
        for i in range(len(words) - 2):
            a, b = lx.DIRECTIONS.get(words[i]), lx.DIRECTIONS.get(words[i + 2])
            if words[i + 1] == "to" and a in WORLD and b in WORLD and WORLD[a][0] == WORLD[b][0] and a != b:
                for k in range(i, i + 3):
                    used[k] = True
                if i > 0 and words[i - 1] == "from":
                    used[i - 1] = True
                return WORLD[a][0]
        return None

    def find_degree(self, words: list[str], used: list[bool]) -> tuple[str, float | None] | None:
        """Degree words: small (``a bit``, ``slightly``), large (``a lot``, ``much``), a percentage,
        a factor (``twice as``, ``half as``, ``3 times as``), or an angle in degrees."""
        degree = None
        for i, word in enumerate(words):
            if used[i]:
                continue
            nxt = words[i + 1] if i + 1 < len(words) else ""
            match = re.fullmatch(r"(\d+(?:\.\d+)?)%", word)
            if match or (lx.is_number(word) and nxt in ("%", "percent")):
                value = float(match.group(1) if match else word)
                degree = ("percent", value)
                used[i] = True
                if not match:
                    used[i + 1] = True
            elif lx.is_number(word) and nxt in ("degree", "degrees"):
                degree = ("degrees", float(word))
                used[i] = used[i + 1] = True
            elif (word in lx.FACTORS or lx.is_number(word) or word in lx.NUMBER_WORDS) and nxt == "times":
                value = float(word) if lx.is_number(word) else float(lx.FACTORS.get(word, lx.NUMBER_WORDS.get(word, 1)))
                degree = ("factor", value)
                used[i] = used[i + 1] = True
            elif word in lx.FACTORS:
                degree = ("factor", lx.FACTORS[word])
                used[i] = word not in lx.CHANGE_VERBS  # "double the width": the verb still says what grows
            elif word in lx.SMALL_DEGREE:
                degree = degree or ("small", None)
                used[i] = True
            elif word in lx.LARGE_DEGREE:
                degree = degree or ("large", None)
                used[i] = True
        return degree

    def find_mentions(self, words: list[str], used: list[bool]) -> list[Mention]:
        singular = [lx.singular(w) for w in words]
        mentions: list[Mention] = []
        first_content = next((i for i, w in enumerate(words) if w not in lx.FILLERS), 0)
        longest = max((len(k) for k in self.phrases), default=1)
        i = 0
        while i < len(words):
            word = words[i]
            prev = words[i - 1] if i else ""
            multi = next((n for n in range(min(longest, len(words) - i), 1, -1)
                          if tuple(singular[i:i + n]) in self.phrases), 0)
            if not multi and word in self.category and singular[i] == word and prev not in lx.QUALIFIERS:
                mentions.append(Mention(tuple(self.shape.parts), i, i + 1, (word,), whole=True))
                used[i] = True
                i += 1
                continue
            if word in lx.WHOLE_WORDS or word in ("them", "they"):
                mentions.append(Mention(tuple(self.shape.parts), i, i + 1, (word,), whole=True,
                                        pronoun=word in ("it", "them", "they")))
                used[i] = True
                i += 1
                continue
            if word in lx.OTHERS_WORDS:
                mentions.append(Mention((), i, i + 1, (word,), others=True))
                used[i] = True
                i += 1
                continue
            matched = False
            for n in range(min(longest, len(words) - i), 0, -1):
                key = tuple(singular[i:i + n])
                if key in self.phrases and not (n == 1 and i == first_content and word == "lower"):
                    labels = self.phrases[key]
                    parts = tuple(p for label in labels for p in self.labels[label])
                    mentions.append(Mention(parts, i, i + n, tuple(words[i:i + n]), labels))
                    for k in range(i, i + n):
                        used[k] = True
                    i += n
                    matched = True
                    break
            if not matched:
                i += 1
        # A one-word label right before another part noun is a position word: "the top shelf".
        merged: list[Mention] = []
        for mention in mentions:
            if merged and not merged[-1].whole and merged[-1].end == mention.start and len(merged[-1].words) == 1 \
                    and merged[-1].words[0] in lx.QUALIFIERS and not mention.whole:
                word = merged.pop().words[0]
                mention = self.qualify(Mention(mention.parts, mention.start - 1, mention.end, mention.words,
                                               mention.labels), [(lx.QUALIFIERS[word],)])
            merged.append(mention)
        mentions = merged
        # "the back" with no label after it: the parts of the object's back.
        for i, word in enumerate(words):
            if used[i] or word != "back":
                continue
            k = i + 1
            while k < len(words) and words[k] in lx.QUALIFIERS and not used[k]:
                k += 1
            nxt_is_part = any(m.start == k for m in mentions)
            prev = words[i - 1] if i else ""
            if nxt_is_part or not (prev in ("the", "its") or prev in self.category):
                continue
            if i >= 2 and words[i - 2] in ("in", "at", "on", "to", "towards") and any(m.end <= i - 2 for m in mentions):
                continue  # "the legs in the back": a position of the legs, not the chair's back
            labels = self._labels_for(word)
            if not labels:
                continue
            parts = tuple(p for label in labels for p in self.labels[label])
            mentions.append(Mention(parts, i, i + 1, (word,), labels))
            used[i] = True
        mentions.sort(key=lambda m: m.start)
        # Position words in front of a part noun narrow it.
        out = []
        for mention in mentions:
            if mention.whole or mention.others:
                out.append(mention)
                continue
            groups: list[list[str]] = [[]]
            k = mention.start - 1
            while k >= 0 and not used[k]:
                word = words[k]
                if word in lx.QUALIFIERS and not (k == first_content and word == "lower"):
                    groups[-1].insert(0, lx.QUALIFIERS[word])
                    used[k] = True
                elif word in ("and", "or", ",") and groups[-1]:
                    groups.append([])
                elif word in ("the", "its"):
                    pass
                else:
                    break
                k -= 1
            groups = [g for g in groups if g]
            out.append(self.qualify(mention, [tuple(g) for g in reversed(groups)]) if groups else mention)
        return out

    def qualify(self, mention: Mention, groups: list[tuple[str, ...]]) -> Mention:
        """Narrow a mention by position words: groups of words are intersections, unioned together."""
        chosen: set[str] = set()
        for words in groups:
            selected = set(mention.parts)
            for word in words:
                selected &= set(self.select(mention, word))
            chosen |= selected
        if not chosen:
            raise NotUnderstood(f"there is no {' '.join(groups[0])} {mention.text}")
        parts = tuple(p for p in mention.parts if p in chosen)
        return Mention(parts, mention.start, mention.end, mention.words, mention.labels,
                       qualifiers=tuple(groups) + mention.qualifiers)

    def select(self, mention: Mention, word: str) -> list[str]:
        """The parts of a mention a position word picks."""
        parts = list(mention.parts)
        if len(parts) == 1:
            return parts
        centres = np.array([self.part(p).centre for p in parts])
        offsets = centres - centres.mean(axis=0)
        threshold = lx_spread(self.size)
        axes = [a for a in range(3) if np.ptp(offsets[:, a]) > threshold]
        ordinals = {"first": 0, "second": 1, "third": 2, "fourth": 3, "fifth": 4}
        if word in ordinals or word == "last":
            if not axes:
                return []
            axis = 1 if 1 in axes else axes[0]
            order = sorted(range(len(parts)), key=lambda i: (offsets[i, axis], parts[i]))
            index = len(order) - 1 if word == "last" else ordinals[word]
            return [parts[order[index]]] if index < len(order) else []
        if word == "middle":
            if len(axes) != 1:
                return [] if axes else parts
            axis = axes[0]
            distance = np.abs(offsets[:, axis])
            return [p for p, d in zip(parts, distance) if d <= distance.min() + threshold]
        side = {"left": (0, -1), "right": (0, 1), "bottom": (1, -1), "top": (1, 1), "back": (2, -1),
                "front": (2, 1)}[word]
        axis, sign = side
        if axis not in axes:
            return parts
        values = offsets[:, axis] * sign
        if len(axes) == 1:
            return [p for p, v in zip(parts, values) if v >= values.max() - threshold]
        reach = float(np.abs(offsets[:, axis]).max())
        return [p for p, v in zip(parts, values) if v > 0.25 * reach]

    def find_intents(self, words: list[str], used: list[bool], mentions: list[Mention]) -> list[Intent]:
        intents: list[Intent] = []
        first_content = next((i for i, w in enumerate(words) if w not in lx.FILLERS), -1)
        count_words: list[Intent] = []
        for i, word in enumerate(words):
            if used[i]:
                continue
            base = lx.lemma(word)
            prev = words[i - 1] if i else ""
            nxt = words[i + 1] if i + 1 < len(words) else ""
            if word in self.plugin_words:
                intents.append(Intent("plugin", 1, direction=self.plugin_words[word]))
                used[i] = True
                continue
            if word in lx.ADJECTIVES or word in lx.EXTRA_COMPARATIVES:
                # "too long" -> shorter; "less wide" -> narrower; "(more|as|not) wide (enough)" -> wider.
                comparative = lx.ADJECTIVES.get(word) or lx.EXTRA_COMPARATIVES[word]
                invert = prev in ("too", "less", "overly") and not used[i - 1]
                intent = self._comparative(comparative)
                if invert:
                    intent = Intent(intent.action, -intent.sign, intent.dimension, intent.direction)
                    used[i - 1] = True
                elif prev in ("more", "as") and i and not used[i - 1]:
                    used[i - 1] = True
                intents.append(intent)
                used[i] = True
                if nxt == "enough":
                    used[i + 1] = True
                continue
            if word in lx.NEGATIONS:
                k = i + 1
                while k < len(words) and words[k] in ("to", "do", "not", "be") and not used[k]:
                    k += 1
                verb = _base_verb(words[k]) if k < len(words) and not used[k] else ""
                if verb in lx.INTENTS or verb in lx.PLAIN_VERBS:
                    intents.append(Intent("keep"))
                    for j in range(i, k + 1):
                        used[j] = True
                continue
            if word in ("more", "less", "extra", "additional") and nxt in lx.DIMENSION_NOUNS \
                    and lx.DIMENSION_NOUNS[nxt][0] != "count":
                # "more height", "less width": a noun form of the comparative.
                action, dimension = lx.DIMENSION_NOUNS[nxt]
                intents.append(Intent(action, 1 if word != "less" else -1, dimension))
                used[i] = used[i + 1] = True
                continue
            if word in lx.POSITIONAL_COMPARATIVES:
                sign = lx.POSITIONAL_COMPARATIVES[word]
                if i == first_content and word == "lower":
                    intents.append(Intent("move", 1, direction="down"))
                else:
                    intents.append(Intent("comparative", sign))
                used[i] = True
            elif base in lx.CHANGE_VERBS:
                sign = lx.CHANGE_VERBS[base]
                noun = next((k for k in range(i + 1, len(words)) if words[k] in lx.DIMENSION_NOUNS and not used[k]),
                            None)
                if noun is None:
                    continue
                action, dimension = lx.DIMENSION_NOUNS[words[noun]]
                intents.append(Intent(action, sign, dimension))
                used[i] = used[noun] = True
            elif word in lx.COUNT_WORDS and nxt not in lx.ADJECTIVES:
                count_words.append(Intent("count", lx.COUNT_WORDS[word]))
                used[i] = True
            elif base in lx.INTENTS:
                intents.append(lx.INTENTS[base])
                used[i] = True
            elif base in lx.EXTRA_COMPARATIVES:
                intents.append(lx.INTENTS[lx.EXTRA_COMPARATIVES[base]])
                used[i] = True
        if not intents:
            intents = count_words
        elif count_words and any(it.action in ("move", "uniform") and it.direction is None for it in intents):
            # "put in another shelf": the count word says what the verb does.
            intents = count_words
        unique: list[Intent] = []
        for intent in intents:
            if intent not in unique and not (intent.action == "keep" and any(u.action == "keep" for u in unique)):
                unique.append(intent)
        return unique

    @staticmethod
    def _comparative(word: str) -> Intent:
        if word in lx.POSITIONAL_COMPARATIVES:
            return Intent("comparative", lx.POSITIONAL_COMPARATIVES[word])
        return lx.INTENTS[word]

    def combine(self, intents: list[Intent], directions: list[str], text: str) -> tuple[list[Intent], list[str]]:
        """Settle intents that depend on direction words (scale up, move apart)."""
        out = []
        for intent in intents:
            if intent.action == "uniform" and directions and directions[0] in ("up", "down"):
                intent = Intent("uniform", intent.sign * (1 if directions[0] == "up" else -1))
                directions = directions[1:]
            elif intent.action == "move" and intent.direction is None and directions and directions[0] in (
                    "outward", "inward"):
                intent = Intent("spread", 1 if directions[0] == "outward" else -1)
                directions = directions[1:]
            elif intent.action == "spread" and directions and directions[0] in ("outward", "inward"):
                intent = Intent("spread", intent.sign * (1 if directions[0] == "outward" else -1))
                directions = directions[1:]
            out.append(intent)
        return out, directions

    # -- from clauses to edits -------------------------------------------------------------

    def seed_ops(self, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        ops: list[SeedOp] = []
        for intent in clause.intents:
            if intent.action == "keep":
                continue
            for mention in clause.mentions:
                if mention.others:
                    raise NotUnderstood(f"'{clause.text}': which parts are 'the rest'?")
                ops.extend(self.edit(intent, mention, clause, reasons))
        if not ops:
            raise NotUnderstood(f"'{clause.text}' asks for no edit")
        if clause.degree is not None:
            ops = [with_degree(op, clause.degree) for op in ops]
            reasons.append(f"'{clause.text}' says how far: at x = 1 the edit reaches "
                           f"{', '.join(op.amount for op in ops)}.")
        return ops

    def secondary(self, clause: Clause, primary_parts: set[str], out: Interpretation) -> None:
        for intent in clause.intents:
            if intent.action == "count":
                for mention in clause.mentions:
                    out.ops.extend(self.edit(intent, mention, clause, out.reasons))
                continue
            kind = HINT_OF.get(intent.action)
            if intent.action == "comparative":
                kind = "translate" if not all(m.whole for m in clause.mentions) else "scale"
            if kind is None:
                raise NotUnderstood(f"'{clause.text}': cannot tell how the parts should follow")
            for mention in clause.mentions:
                if mention.others or (mention.whole and kind == "keep"):
                    parts = sorted(set(self.shape.parts) - primary_parts)
                    key_parts = {p: p for p in parts}
                elif mention.whole:
                    raise NotUnderstood(f"'{clause.text}': which parts should {intent.action}?")
                else:
                    parts = list(mention.parts)
                    key_parts = {}
                    for label in mention.labels:
                        members = [p for p in self.labels[label] if p in parts]
                        if len(members) == len(self.labels[label]) and members:
                            key_parts[label] = label
                        else:
                            key_parts.update({p: p for p in members})
                for p in parts:
                    out.hints[p] = kind
                for key in key_parts:
                    out.hint_keys[key] = kind
                out.hint_reasons.append(f"'{clause.text}' asks the {mention.text} to {kind}")

    def edit(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        action = intent.action
        if action == "comparative":
            if mention.whole:
                intent, action = Intent("size", intent.sign, "height"), "size"
            else:
                intent, action = Intent("move", 1, direction="up" if intent.sign > 0 else "down"), "move"
        if mention.whole:
            return self.whole_edit(intent, clause, reasons)
        handler = getattr(self, f"edit_{action}", None)
        if handler is None:
            raise NotUnderstood(f"'{clause.text}': cannot {action} parts")
        return handler(intent, mention, clause, reasons)

    def whole_edit(self, intent: Intent, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        main = self.main_part()
        name = self.shape.name
        if intent.action == "move" and intent.direction in ("up", "down") and not clause.directions:
            # "raise the chair", "lower the cabinet": the object gets taller or lower.
            intent = Intent("size", 1 if intent.direction == "up" else -1, "height")
        if intent.action == "size":
            dimension = intent.dimension
            if clause.span_axis is not None:
                dimension = ("width", "height", "depth")[clause.span_axis]
            if dimension == "length":
                dimension = "height" if intent.sign < 0 and "shorter" in clause.text.split() else (
                    "width" if self.part(main).size[0] >= self.part(main).size[2] else "depth")
            if dimension == "height" and not self.supports():
                # Without legs, the height of the object is the height of its tallest part.
                free = [p for p in self.shape.parts if p not in self.kept] or list(self.shape.parts)
                tallest = max(free, key=lambda p: (round(float(self.part(p).size[1]), 6), p == main))
                reasons.append(f"The whole {name} should get {'taller' if intent.sign > 0 else 'lower'}; {tallest} "
                               "is its tallest part, so the seed edit stretches it along y from its bottom.")
                return [self._scale_1d(tallest, 1, intent.sign)]
            if dimension == "height" and self.supports():
                mention = Mention(self.supports(), 0, 0, ("supports",), tuple(
                    sorted({self.part(p).label for p in self.supports()})))
                reasons.append(f"The whole {name} should get {'taller' if intent.sign > 0 else 'lower'}; its height "
                               "comes from the parts it stands on, so they change length.")
                return self.edit_size(Intent("size", intent.sign, "height"), mention, clause, [])
            axis = {"width": 0, "height": 1, "depth": 2}[dimension]
            reasons.append(f"The whole {name} should change {dimension}; {main} is the part the others attach to, "
                           f"so the seed edit scales it along {AXIS_WORDS[axis]}.")
            return [self._scale_1d(main, axis, intent.sign)]
        if intent.action == "uniform":
            reasons.append(f"The whole {name} should get {'bigger' if intent.sign > 0 else 'smaller'}; {main} is the "
                           "part the others attach to, so the seed edit scales it uniformly.")
            return [SeedOp("scale_3d", main, GROW if intent.sign > 0 else SHRINK,
                           origin=Origin("face", main, ("bottom",)))]
        raise NotUnderstood(f"'{clause.text}': to {intent.action} something, name the part")

    def _scale_1d(self, pid: str, axis: int, sign: int) -> SeedOp:
        origin = Origin("face", pid, ("bottom",)) if axis == 1 else Origin("center", pid)
        return SeedOp("scale_1d", pid, GROW if sign > 0 else SHRINK, origin=origin,
                      dirs=(("dir", AXIS_WORDS[axis]),))

    def _reps(self, mention: Mention) -> list[tuple[str, ...]]:
        """Symmetric components of a mention, one per label (so a multi-label mention keeps its labels)."""
        comps = []
        for label in mention.labels or (None,):
            members = [p for p in mention.parts if label is None or self.part(p).label == label]
            if members:
                comps.extend(self.components(members))
        return comps

    def edit_size(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        dimension = intent.dimension
        comps = self._reps(mention)
        if len(mention.labels) > 1:
            # A part made of several labels (a chair's back): stretch the piece that spans that dimension.
            def reach(comp: tuple[str, ...]) -> float:
                axis = self._dimension_axis(dimension, comp[0], clause.span_axis)
                return float(self.part(comp[0]).size[axis])

            comps = [max(comps, key=lambda c: (reach(c), -len(c[0]), c[0]))]
        ops = []
        for comp in comps:
            rep = comp[0]
            axis = self._dimension_axis(dimension, rep, clause.span_axis)
            ops.append(self._scale_1d(rep, axis, intent.sign))
            reasons.append(f"The {mention.text} should get {'longer' if intent.sign > 0 else 'shorter'} along "
                           f"{AXIS_WORDS[axis]} ({dimension}); {rep} is edited"
                           + (" and the parts mirroring it follow." if len(comp) > 1 else "."))
        return ops

    def _dimension_axis(self, dimension: str | None, pid: str, span: int | None = None) -> int:
        if span is not None and dimension in ("length", None):
            return span
        if dimension == "length":
            return self._longest(self.part(pid).size)
        return {"width": 0, "height": 1, "depth": 2}[dimension or "width"]

    def edit_thickness(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        ops = []
        amount = GROW if intent.sign > 0 else SHRINK
        for comp in self._reps(mention):
            rep = comp[0]
            size = np.asarray(self.part(rep).size)
            order = np.argsort(size)
            small, middle, large = (int(a) for a in order)
            if size[small] < 0.25 * size[middle]:
                origin = Origin("face", rep, ("bottom",)) if small == 1 else Origin("center", rep)
                ops.append(SeedOp("scale_1d", rep, amount, origin=origin, dirs=(("dir", AXIS_WORDS[small]),)))
                reasons.append(f"{rep} is a flat plate, so thickness is its thin side, along {AXIS_WORDS[small]}.")
            elif size[large] > 2 * size[middle]:
                ops.append(SeedOp("scale_2d", rep, amount, origin=Origin("center", rep),
                                  dirs=(("normal", AXIS_WORDS[large]),)))
                reasons.append(f"{rep} is long and thin, so thickness is its cross-section: scale it across "
                               f"{AXIS_WORDS[large]}.")
            else:
                ops.append(SeedOp("scale_3d", rep, amount, origin=Origin("center", rep)))
                reasons.append(f"{rep} is a block; thicker means bigger all round.")
        return ops

    def edit_uniform(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        ops = []
        for comp in self._reps(mention):
            rep = comp[0]
            ops.append(SeedOp("scale_3d", rep, GROW if intent.sign > 0 else SHRINK, origin=Origin("center", rep)))
            reasons.append(f"{rep} should get {'bigger' if intent.sign > 0 else 'smaller'}: scale it about its centre.")
        return ops

    def _direction(self, intent: Intent, clause: Clause, what: str) -> str:
        word = intent.direction or (clause.directions[0] if clause.directions else None)
        if word is None:
            raise NotUnderstood(f"'{clause.text}' does not say which way to {what}")
        return word

    def _rigid_targets(self, mention: Mention) -> list[tuple[str, tuple[str, ...]]]:
        """(operand, parts) per rigidly moving piece: a whole group moves through its virtual parent."""
        out = []
        for comp in self._reps(mention):
            group = self.group_of(comp)
            if group is not None and set(group.members) == set(comp):
                out.append((group.id, comp))
            else:
                out.append((comp[0], comp))
        return out

    def edit_move(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        word = self._direction(intent, clause, "move")
        if word not in WORLD:
            raise NotUnderstood(f"'{clause.text}': cannot move parts {word}")
        axis, sign = WORLD[word]
        step = 0.25 * float(self.extent[axis])
        ops = []
        for operand, _ in self._rigid_targets(mention):
            ops.append(SeedOp("translate", operand, _amount(step), dirs=(("dir", _axis_word(axis, sign)),)))
            reasons.append(f"The {mention.text} should move {word}: translate {operand} along "
                           f"{_axis_word(axis, sign)}.")
        return ops

    def _outward(self, pid: str) -> tuple[int, int] | None:
        """The horizontal world direction pointing from the shape's centre to the part."""
        offset = np.asarray(self.part(pid).centre) - self.centre
        horizontal = [0, 2]
        axis = max(horizontal, key=lambda a: (abs(offset[a]), -a))
        if abs(offset[axis]) < lx_spread(self.size):
            return None
        return axis, int(np.sign(offset[axis]))

    def _contact(self, lo: np.ndarray, hi: np.ndarray, other: str) -> np.ndarray | None:
        """The centre of the overlap of a box with another part's box, if they touch."""
        low = np.maximum(lo, self.part(other).lo)
        high = np.minimum(hi, self.part(other).hi)
        if np.any(high < low - 1e-3 * self.size):
            return None
        return (low + high) / 2

    def edit_tilt(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        main = self.main_part()
        main_centre = np.asarray(self.part(main).centre)
        word = intent.direction or (clause.directions[0] if clause.directions else None)
        if word is None:
            word = "back" if any(label.startswith("back") for label in mention.labels) else "outward"
        multi = len(mention.labels) > 1
        # The part's long axis decides what tilts: the longest part of the mention sets it.
        longest = max(mention.parts, key=lambda p: (max(self.part(p).size), p))
        long_axis = self._longest(self.part(longest).size)
        ops = []
        for operand, comp in self._rigid_targets(mention):
            rep = comp[0]
            lo, hi = self.bounds(mention.parts if multi else (rep,))
            # The pivot is the end nearer the part everything attaches to; the other end swings.
            ends = [(1, hi[long_axis]), (-1, lo[long_axis])]
            pivot_sign = min(ends, key=lambda e: (abs(e[1] - main_centre[long_axis]), e[0]))[0]
            free = np.zeros(3)
            free[long_axis] = -pivot_sign
            if word in ("outward", "inward"):
                found = self._outward(rep)
                if found is None:
                    raise NotUnderstood(f"'{clause.text}': {rep} sits at the centre, so 'outward' has no direction")
                axis, sign = found
                sign = sign if word == "outward" else -sign
            elif word in WORLD:
                axis, sign = WORLD[word]
            else:
                raise NotUnderstood(f"'{clause.text}': cannot tilt towards '{word}'")
            d = np.zeros(3)
            d[axis] = sign
            n = np.cross(free, d)
            if np.linalg.norm(n) < 0.5:
                raise NotUnderstood(f"'{clause.text}': {rep} points {word} already; tilting it that way does nothing")
            n_axis = int(np.argmax(np.abs(n)))
            axis_word = _axis_word(n_axis, int(np.sign(n[n_axis])))
            pivot_face = SIDE[(long_axis, pivot_sign)]
            contact = self._contact(lo, hi, main) if main not in mention.parts else None
            if contact is not None:
                # Turning about the middle of the contact with the core part keeps that contact.
                origin = Origin("point", point=tuple(float(round(v, 4)) for v in contact))
            elif multi or operand != rep:
                point = (lo + hi) / 2
                point[long_axis] = hi[long_axis] if pivot_sign > 0 else lo[long_axis]
                origin = Origin("point", point=tuple(float(round(v, 4)) for v in point))
            else:
                origin = Origin("face", rep, (pivot_face,))
            ops.append(SeedOp("rotate", operand, TILT_AMOUNT, origin=origin, dirs=(("axis", axis_word),)))
            where = f"where it meets {main}" if contact is not None else f"at its {pivot_face} end"
            adverb = {"back": "backwards", "front": "forwards"}.get(word, word)
            reasons.append(f"Tilting the {mention.text} {adverb} turns {operand} about {axis_word} through the point "
                           f"{where}, so its other end swings {adverb}.")
        return ops

    def edit_rotate(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        lo, hi = self.bounds(mention.parts)
        multi = len(mention.labels) > 1
        ops = []
        for operand, comp in self._rigid_targets(mention):
            rep = comp[0]
            if multi or operand != rep:
                origin = Origin("point", point=tuple(float(round(v, 4)) for v in (lo + hi) / 2))
            else:
                origin = Origin("center", rep)
            ops.append(SeedOp("rotate", operand, ROTATE_AMOUNT, origin=origin, dirs=(("axis", "y"),)))
            reasons.append(f"Rotating the {mention.text} turns {operand} about the vertical through its centre.")
        return ops

    def edit_open(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        """Each door of a pair swings about its own outer front edge, so a mirrored pair opens
        mirrored; the frame it swings away from stays where it is (a ``keep`` hint, see
        :meth:`frames`), since opening a door does not move the cabinet."""
        ops = []
        opened = [p for comp in self._reps(mention) for p in comp]
        for pid in opened:
            offset = float(self.part(pid).centre[0] - self.centre[0])
            outer = "left" if offset <= 0 else "right"
            inner_sign = 1 if outer == "left" else -1
            free = np.array([inner_sign, 0.0, 0.0])
            n = np.cross(free, np.array([0.0, 0.0, 1.0]))
            axis_word = _axis_word(1, int(np.sign(n[1])))
            ops.append(SeedOp("rotate", pid, OPEN_AMOUNT, origin=Origin("edge", pid, (outer, "front")),
                              dirs=(("axis", axis_word),)))
            reasons.append(f"{pid} opens about its hinge, the {outer} front edge, swinging its free edge to the front.")
        for frame in self.frames(opened):
            self.held[frame] = f"{frame} is what the {mention.text} swing away from, so it stays where it is"
        return ops

    def frames(self, opened: Sequence[str]) -> list[str]:
        """Parts an opened part is attached to that hold other parts too (a cabinet's body, not a
        handle that only rides on the door)."""
        moving = set(opened)
        out = []
        for relation in self.shape.relations.values():
            if relation.kind != "attachment" or not moving & set(relation.members):
                continue
            for other in set(relation.members) - moving:
                partners = {m for r in self.shape.relations_of(other) if r.kind == "attachment"
                            for m in r.members} - {other}
                if partners - moving and other not in out:
                    out.append(other)
        return sorted(out)

    def edit_taper(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        main_centre = np.asarray(self.part(self.main_part()).centre)
        ops = []
        amount = SHRINK if intent.sign < 0 else GROW
        for comp in self._reps(mention):
            rep = comp[0]
            part = self.part(rep)
            axis = self._longest(part.size)
            if clause.directions and clause.directions[0] in WORLD and WORLD[clause.directions[0]][0] == axis:
                sign = WORLD[clause.directions[0]][1]
            else:
                ends = [(1, part.hi[axis]), (-1, part.lo[axis])]
                sign = max(ends, key=lambda e: (abs(e[1] - main_centre[axis]), e[0]))[0]
            face = SIDE[(axis, sign)]
            ops.append(SeedOp("scale_2d", rep, amount, feature=(face,), origin=Origin("face", rep, (face,)),
                              dirs=(("normal", AXIS_WORDS[axis]),)))
            reasons.append(f"Tapering {rep} {'narrows' if intent.sign < 0 else 'widens'} its {face} end: scale that "
                           f"face across {AXIS_WORDS[axis]}.")
        return ops

    def edit_plugin(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        """A plugin operator asked for by one of its words: direction fields along the part's long
        axis, the origin at its centre, the amount ``x``."""
        from parsel_core.plugins import edit_operators

        cls = edit_operators()[intent.direction]
        ops = []
        for comp in self._reps(mention):
            rep = comp[0]
            axis = AXIS_WORDS[self._longest(self.part(rep).size)]
            origin = Origin("center", rep) if "origin" in getattr(cls, "point_fields", ()) else None
            dirs = tuple((name, axis) for name in getattr(cls, "unit_fields", ()))
            ops.append(SeedOp(cls.name, rep, GROW, origin=origin, dirs=dirs))
            reasons.append(f"'{clause.text}' asks for the {cls.name} operator on {rep}, about its long axis "
                           f"{axis} through its centre.")
        return ops

    def _group_within(self, mention: Mention):
        """The largest translation or rotation group whose members the mention names."""
        groups = [g for g in self.shape.groups() if set(g.members) <= set(mention.parts)]
        return max(groups, key=lambda g: (len(g.members), g.id)) if groups else None

    def edit_spread(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        ops = []
        group = self._group_within(mention)
        if group is not None and not mention.qualified:
            reasons.append(f"The {mention.text} are a repeated row ({group.id}); spacing them "
                           f"{'out' if intent.sign > 0 else 'closer'} changes the group's step.")
            return [SeedOp("change_delta", group.id, GROW if intent.sign > 0 else SHRINK, mode="bottom_up",
                           group=True)]
        for comp in self._reps(mention):
            group = self.group_of(comp)
            if group is not None and set(group.members) == set(comp):
                ops.append(SeedOp("change_delta", group.id, GROW if intent.sign > 0 else SHRINK, mode="bottom_up",
                                  group=True))
                reasons.append(f"The {mention.text} are a repeated row ({group.id}); spacing them "
                               f"{'out' if intent.sign > 0 else 'closer'} changes the group's step.")
                continue
            rep = comp[0]
            mirror = next((r for r in self.shape.relations_of(rep) if r.kind == "reflection"
                           and set(r.members) <= set(comp) and r.normal_axis is not None), None)
            if mirror is None:
                raise NotUnderstood(f"'{clause.text}': the {mention.text} are not a mirrored pair or a repeated row")
            axis = mirror.normal_axis
            offset = float(self.part(rep).centre[axis] - mirror.plane_offset)
            sign = int(np.sign(offset)) * intent.sign
            step = 0.5 * abs(offset)
            ops.append(SeedOp("translate", rep, _amount(step), dirs=(("dir", _axis_word(axis, sign)),)))
            reasons.append(f"Spreading the {mention.text} moves {rep} {'away from' if intent.sign > 0 else 'towards'} "
                           f"the mirror plane of {mirror.id}; its mirror images follow.")
        return ops

    def edit_count(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        group = self._group_within(mention) or (self.group_of(mention.parts[:1]) if mention.parts else None)
        if group is None:
            raise NotUnderstood(f"'{clause.text}': the {mention.text} are not a repeated row or ring, so their number "
                                "cannot change")
        k = len(group.members)
        if clause.number is not None:
            n = min(clause.number, k - 1) if intent.sign < 0 else clause.number
            amount = ("x" if n == 1 else f"{n} * x") if intent.sign > 0 else ("-x" if n == 1 else f"-{n} * x")
        elif intent.sign > 0:
            amount = f"{k} * x"
        else:
            amount = "-x" if k - 1 == 1 else f"-{k - 1} * x"
        reasons.append(f"The {mention.text} form the group {group.id} of {k}; the seed edit changes its count "
                       "within the same span.")
        return [SeedOp("change_count", group.id, amount, mode="top_down", group=True)]

    def edit_keep(self, intent: Intent, mention: Mention, clause: Clause, reasons: list[str]) -> list[SeedOp]:
        return []

    # -- relations the request breaks --------------------------------------------------------

    def find_breaks(self, clauses: Sequence[Clause], out: Interpretation) -> None:
        singled: set[str] = set()
        for clause in clauses:
            for mention in clause.mentions:
                if mention.qualified:
                    singled.update(mention.parts)
        broken: dict[str, str] = {}
        # Moving or tilting mirrored parts the same world way breaks mirrors across that way.
        for clause in clauses:
            for intent in clause.intents:
                if intent.action not in ("move", "tilt"):
                    continue
                word = intent.direction or (clause.directions[0] if clause.directions else None)
                if word not in WORLD:
                    continue
                axis = WORLD[word][0]
                for mention in clause.mentions:
                    for relation in self.shape.relations.values():
                        if relation.kind == "reflection" and relation.normal_axis == axis \
                                and set(relation.members) <= set(mention.parts):
                            broken[relation.id] = (f"the request moves {relation.members[0]} and "
                                                   f"{relation.members[1]} the same way ({word}), across their mirror")
        for relation in self.shape.relations.values():
            if relation.kind not in ("reflection", "translation", "rotation"):
                continue
            inside = [m for m in relation.members if m in singled]
            if inside and len(inside) < len(relation.members):
                broken[relation.id] = (f"the request singles out {', '.join(inside)} but not "
                                       f"{', '.join(m for m in relation.members if m not in singled)}")
        # Mirrors across the same plane follow: a handle on the edited door stops mirroring the other handle.
        attached = {}
        for relation in self.shape.relations.values():
            if relation.kind == "attachment":
                a, b = relation.members
                attached.setdefault(a, set()).add(b)
                attached.setdefault(b, set()).add(a)
        # A part all of whose attachments are to singled-out parts is carried along with them.
        carried = {p for p, partners in attached.items() if p not in singled and partners and partners <= singled}
        planes = {(self.shape.relations[r].normal_axis, round(self.shape.relations[r].plane_offset or 0.0, 3))
                  for r in broken if self.shape.relations[r].kind == "reflection"}
        for relation in self.shape.relations.values():
            if relation.kind != "reflection" or relation.id in broken:
                continue
            if (relation.normal_axis, round(relation.plane_offset or 0.0, 3)) not in planes:
                continue
            a, b = relation.members
            if (a in carried) != (b in carried):
                carrier = a if a in carried else b
                broken[relation.id] = (f"{carrier} is carried by a part the request singles out, "
                                       "and its mirror image is not")
        out.breaks = sorted(broken, key=lambda r: list(self.shape.relations).index(r))
        out.break_reasons = broken
        self.broken = set(broken)


def _base_verb(word: str) -> str:
    """A verb's base form, also for plain verbs the edit lexicon does not hold (``changing``)."""
    base = lx.lemma(word)
    if base != word or word in lx.PLAIN_VERBS:
        return base
    for suffix in ("ing", "ed", "es", "s"):
        stem = word[: -len(suffix)] if word.endswith(suffix) else ""
        for candidate in (stem, stem + "e"):
            if candidate in lx.PLAIN_VERBS:
                return candidate
    return word


def plugin_words() -> dict[str, str]:
    """Word -> operator name, from the ``words`` attribute of registered operators (plugins extend
    the offline lexicon this way: docs/plugins.md)."""
    from parsel_core.plugins import edit_operators

    out: dict[str, str] = {}
    for name, cls in sorted(edit_operators().items()):
        for word in getattr(cls, "words", ()) or ():
            out[str(word).lower()] = name
    return out


def _coefficient(amount: str) -> float:
    from parsel_core.language.amounts import amount_values

    return amount_values(amount, "x", 0.0, 1.0, samples=2)[1]


def _linear(value: float) -> str:
    return "x" if value == 1 else "-x" if value == -1 else f"{value:.6g} * x"


#: What degree words make of a default amount (docs/language.md, "Degree words").
SMALL_GROW, SMALL_SHRINK, LARGE_GROW, LARGE_SHRINK = 0.25, -0.2, 2.0, -0.75
SCALE_OPS = ("scale_1d", "scale_2d", "scale_3d", "change_delta")


def with_degree(op: SeedOp, degree: tuple[str, float | None]) -> SeedOp:
    """The op with its amount set by a degree word: sizes get a factor, moves and turns a multiple."""
    kind, value = degree
    coefficient = _coefficient(op.amount)
    sign = 1.0 if coefficient >= 0 else -1.0
    if op.op in SCALE_OPS:
        if kind == "small":
            new = SMALL_GROW if sign > 0 else SMALL_SHRINK
        elif kind == "large":
            new = LARGE_GROW if sign > 0 else LARGE_SHRINK
        elif kind == "percent":
            new = sign * min(value, 100.0 if sign > 0 else 95.0) / 100.0
        elif kind == "factor":
            new = value - 1.0
        else:
            return op
    elif op.op in ("translate", "rotate"):
        if kind == "degrees" and op.op == "rotate":
            return replace(op, amount=f"{sign * value:g} * pi / 180 * x")
        scale = {"small": 0.25 if op.op == "translate" else 1 / 3, "large": 2.0}.get(kind)
        if kind == "percent" and op.op == "translate":
            scale = value / 100.0 / 0.25  # a move's default is a quarter of the shape's extent
        if scale is None:
            return op
        new = coefficient * scale
    else:
        return op
    return replace(op, amount=_linear(round(new, 6)))


def lx_spread(size: float) -> float:
    """Distances below this are 'the same place' (2% of the shape's size, as in the description)."""
    return 0.02 * size


def interpret(shape: ShapeSummary, request: str) -> Interpretation:
    """Read ``request`` about ``shape``; raises :class:`NotUnderstood`."""
    return Interpreter(shape).interpret(request)
