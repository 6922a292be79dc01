"""The words the offline interpreter knows, and how it normalises what it reads.

Everything here is data: edit verbs and comparatives (with the kind of edit they ask
for), directions, position qualifiers, synonyms of part labels, names of object
categories, and the filler words it may ignore. A word in a request that is none of
these, and not a part label of the shape, makes the interpreter say it does not
understand: the list of fillers is what it may skip, not a licence to guess.
"""

from __future__ import annotations

import re
from dataclasses import dataclass


@dataclass(frozen=True)
class Intent:
    """What a verb or comparative asks for.

    ``action``: ``size`` (stretch along a dimension), ``thickness``, ``uniform``, ``move``,
    ``tilt``, ``rotate``, ``open``, ``taper``, ``spread``, ``count``, ``keep``;
    ``sign``: +1 more / -1 less; ``dimension``: ``width``/``length``/``height``/``depth``
    for ``size``; ``direction``: a direction word the verb implies (``raise`` -> up).
    """

    action: str
    sign: int = 1
    dimension: str | None = None
    direction: str | None = None


INTENTS: dict[str, Intent] = {}


def _add(words: str, intent: Intent) -> None:
    for word in words.split():
        INTENTS[word] = intent


_add("wider widen broader broaden", Intent("size", 1, "width"))
_add("narrower narrow", Intent("size", -1, "width"))
_add("longer lengthen extend elongate stretch", Intent("size", 1, "length"))
_add("shorter shorten", Intent("size", -1, "length"))
_add("taller heighten", Intent("size", 1, "height"))
_add("deeper deepen", Intent("size", 1, "depth"))
_add("shallower", Intent("size", -1, "depth"))
_add("thicker thicken chunkier beefier fatter sturdier stouter", Intent("thickness", 1))
_add("thinner thin slimmer slim slender slenderer skinnier daintier", Intent("thickness", -1))
_add("bigger larger enlarge grow", Intent("uniform", 1))
_add("smaller shrink", Intent("uniform", -1))
_add("scale resize", Intent("uniform", 1))
_add("raise lift elevate", Intent("move", 1, direction="up"))
_add("drop sink", Intent("move", 1, direction="down"))
_add("move shift slide push pull offset displace put bring", Intent("move", 1))
_add("tilt lean slant incline angle cant", Intent("tilt", 1))
_add("recline", Intent("tilt", 1, direction="back"))
_add("splay", Intent("tilt", 1, direction="outward"))
_add("rotate turn spin swivel twist", Intent("rotate", 1))
_add("open", Intent("open", 1))
_add("taper", Intent("taper", -1))
_add("flare", Intent("taper", 1))
_add("spread space separate", Intent("spread", 1))
_add("bunch squeeze cluster", Intent("spread", -1))
_add("add", Intent("count", 1))
_add("remove delete", Intent("count", -1))
_add("keep fix fixed hold leave preserve maintain unchanged freeze frozen stay stays", Intent("keep"))

#: Plain adjectives and the comparative they grade (``too long`` asks for ``shorter``,
#: ``less wide`` for ``narrower``, ``twice as thick`` for ``thicker``).
ADJECTIVES: dict[str, str] = {
    "long": "longer", "short": "shorter", "wide": "wider", "broad": "wider", "narrow": "narrower",
    "tall": "taller", "high": "higher", "low": "lower", "deep": "deeper", "shallow": "shallower",
    "thick": "thicker", "thin": "thinner", "fat": "thicker", "chunky": "thicker", "skinny": "thinner",
    "slim": "thinner", "slender": "thinner", "big": "bigger", "large": "bigger", "huge": "bigger",
    "small": "smaller", "tiny": "smaller",
}
#: Comparatives the intents table does not hold, as the intent word they mean.
EXTRA_COMPARATIVES = {"shallower": "shallower", "narrower": "narrower", "broader": "wider", "fatter": "thicker"}
#: Degree words: how far the slider's range goes (docs/language.md, "Degree words").
SMALL_DEGREE = frozenset({"slightly", "bit", "little", "tad", "touch", "somewhat", "marginally", "fraction",
                          "smidge", "hair"})
LARGE_DEGREE = frozenset({"lot", "much", "way", "far", "significantly", "considerably", "substantially",
                          "dramatically", "greatly", "lots", "hugely", "massively", "heaps", "loads"})
#: ``twice as long``: the factor a size becomes.
FACTORS = {"twice": 2.0, "double": 2.0, "doubled": 2.0, "triple": 3.0, "thrice": 3.0, "half": 0.5, "halve": 0.5}
#: Phrases read as another word before anything else: idioms and noun forms.
IDIOMS: dict[tuple[str, ...], tuple[str, ...]] = {
    ("get", "rid", "of"): ("remove",), ("do", "away", "with"): ("remove",), ("take", "away"): ("remove",),
    ("take", "out"): ("remove",), ("squeeze", "in"): ("add",), ("fit", "in"): ("add",), ("put", "in"): ("add",),
    ("throw", "in"): ("add",), ("swing", "open"): ("open",), ("swing", "out"): ("open",), ("swing",): ("open",),
    ("further", "apart"): ("apart",), ("farther", "apart"): ("apart",), ("more", "spread", "out"): ("apart",),
    ("as", "they", "are"): (), ("as", "it", "is"): (), ("as", "is"): (), ("the", "way", "they", "are"): (),
    ("the", "way", "it", "is"): (), ("alone",): (), ("in", "place"): (), ("if", "possible"): (),
    ("thank", "you"): (), ("i", "think"): (), ("i", "guess"): (), ("i", "feel"): (), ("in", "my", "opinion"): (),
    ("kind", "of"): (), ("sort", "of"): (), ("a", "bit"): ("bit",), ("a", "little", "bit"): ("bit",),
    ("a", "little"): ("bit",), ("a", "tad"): ("bit",), ("a", "touch"): ("bit",), ("a", "lot"): ("lot",),
    ("a", "great", "deal"): ("lot",), ("a", "tiny", "bit"): ("bit",), ("just", "a", "bit"): ("bit",),
    ("not", "enough"): (), ("side", "to", "side"): ("left", "to", "right"),
}
#: Words spelled the way people type in chat, as the word they stand for.
SPELLINGS = {"plz": "please", "pls": "please", "u": "you", "ur": "your", "r": "are", "thx": "thanks",
             "abit": "bit", "alot": "lot", "kinda": "somewhat", "sorta": "somewhat", "lil": "little"}
#: Possessives and determiners that may open a phrase of purpose (``for my kids``).
DETERMINERS = frozenset({"a", "an", "the", "my", "our", "your", "his", "her", "their", "this", "that", "these",
                         "those", "some", "two", "three", "four", "five", "small", "little", "young", "new", "big"})

#: Comparatives whose meaning depends on the target: ``make the table lower`` (height)
#: versus ``make the seat lower`` (its position).
POSITIONAL_COMPARATIVES = {"higher": 1, "lower": -1}
#: Count words: ``more slats``, ``fewer shelves``.
COUNT_WORDS = {"more": 1, "additional": 1, "extra": 1, "another": 1, "fewer": -1, "less": -1}
#: Verbs that take a dimension noun: ``increase the width of the seat``.
CHANGE_VERBS = {"increase": 1, "decrease": -1, "reduce": -1, "lessen": -1, "double": 1, "halve": -1}
DIMENSION_NOUNS = {
    "width": ("size", "width"), "length": ("size", "length"), "height": ("size", "height"),
    "depth": ("size", "depth"), "thickness": ("thickness", None), "size": ("uniform", None),
    "number": ("count", None), "count": ("count", None), "spacing": ("spread", None), "gap": ("spread", None),
    "gaps": ("spread", None), "distance": ("spread", None), "space": ("spread", None),
}

#: Direction words (world): +x right, +y up, +z front. ``outward``/``inward`` are relative.
DIRECTIONS: dict[str, str] = {
    "top": "up", "bottom": "down", "up": "up", "upward": "up", "upwards": "up", "higher": "up", "above": "up",
    "skyward": "up",
    "down": "down", "downward": "down", "downwards": "down", "below": "down", "floor": "down", "ground": "down",
    "left": "left", "leftward": "left", "leftwards": "left",
    "right": "right", "rightward": "right", "rightwards": "right",
    "forward": "front", "forwards": "front", "front": "front", "frontward": "front", "frontwards": "front",
    "back": "back", "backward": "back", "backwards": "back", "rear": "back", "rearward": "back",
    "rearwards": "back", "behind": "back",
    "outward": "outward", "outwards": "outward", "out": "outward", "apart": "outward", "outside": "outward",
    "away": "outward",
    "inward": "inward", "inwards": "inward", "in": "inward", "together": "inward", "closer": "inward",
    "inside": "inward", "nearer": "inward", "center": "inward", "centre": "inward", "middle": "inward",
}
#: Position qualifiers in front of a part noun: ``the front legs``, ``the top shelf``.
QUALIFIERS: dict[str, str] = {
    "front": "front", "back": "back", "rear": "back", "left": "left", "right": "right",
    "top": "top", "upper": "top", "highest": "top", "topmost": "top", "uppermost": "top",
    "bottom": "bottom", "lower": "bottom", "lowest": "bottom", "bottommost": "bottom", "lowermost": "bottom",
    "leftmost": "left", "rightmost": "right", "frontmost": "front", "backmost": "back",
    "middle": "middle", "center": "middle", "centre": "middle", "central": "middle",
    "first": "first", "second": "second", "third": "third", "fourth": "fourth", "fifth": "fifth",
    "last": "last",
}
#: Synonyms of part labels: a word (singular) -> label words it may stand for.
SYNONYMS: dict[str, tuple[str, ...]] = {
    "foot": ("leg",), "feet": ("leg",), "cushion": ("seat",), "seating": ("seat",),
    "tabletop": ("top",), "worktop": ("top",), "countertop": ("top",), "surface": ("top", "seat"),
    "skirt": ("apron",), "stretcher": ("rail", "apron"),
    "knob": ("handle",), "pull": ("handle",),
    "shelf": ("board", "shelf"), "plank": ("board",), "board": ("board", "shelf"),
    "spindle": ("slat",), "bar": ("slat", "rail"), "slat": ("slat",),
    "upright": ("upright",), "post": ("upright", "leg"), "stile": ("upright",),
    "backrest": ("back",), "backboard": ("back_panel",),
    "base": ("plinth", "base"), "kickboard": ("plinth",), "plinth": ("plinth",),
    "carcass": ("body",), "case": ("body",), "frame": ("body", "frame"), "box": ("body",),
    "armrest": ("arm",), "arm": ("arm",), "side": ("side_panel", "side"), "drawer": ("drawer",),
}
#: Multi-word synonyms, matched before single words.
PHRASES: dict[tuple[str, ...], tuple[str, ...]] = {
    ("table", "top"): ("top",), ("top", "rail"): ("back_rail", "rail"), ("crest", "rail"): ("back_rail",),
    ("back", "post"): ("back_upright",), ("back", "rest"): ("back",), ("toe", "kick"): ("plinth",),
    ("side", "panel"): ("side_panel",), ("back", "panel"): ("back_panel",),
}
#: Part nouns of furniture in general: a request naming one the shape lacks is told so.
PART_NOUNS = frozenset(set(SYNONYMS) | {w for targets in SYNONYMS.values() for w in targets} | set("""
arm armrest drawer wheel caster castor cushion headboard footboard mattress shade bulb pole leg seat back top
door handle knob shelf board panel rail slat spindle upright stretcher apron plinth base frame drawer hinge
lid roof wing footrest headrest""".split()))
#: Words naming the whole object, by category (the shape's name picks the category).
CATEGORIES: dict[str, tuple[str, ...]] = {
    "chair": ("chair", "stool", "armchair"),
    "table": ("table", "desk"),
    "cabinet": ("cabinet", "cupboard", "sideboard", "dresser", "wardrobe", "closet"),
    "storage": ("storage", "cabinet", "cupboard", "bookcase", "bookshelf", "shelving", "dresser", "wardrobe"),
    "shelf": ("shelf", "bookcase", "bookshelf", "shelving", "rack"),
    "bed": ("bed",), "lamp": ("lamp",), "sofa": ("sofa", "couch"),
}
WHOLE_WORDS = ("it", "everything", "whole", "entire", "overall", "object", "furniture", "model", "shape",
               "piece", "thing", "unit")
#: Pronouns that point back at the parts a previous clause named (``the seat, make it deeper``).
PRONOUNS = frozenset({"it", "them", "they", "its", "their", "these", "those", "this", "that", "one", "ones"})
OTHERS_WORDS = ("else", "rest", "remaining", "other", "others")
#: Labels of parts that hold an object up: "taller" lengthens them.
SUPPORT_LABELS = ("leg", "foot", "stand", "pedestal")
#: Labels of the part an object is built around, in order of preference.
CORE_LABELS = ("seat", "top", "tabletop", "body", "frame", "base")
#: Words that may be skipped.
FILLERS = frozenset("""
a an the this that these those its their his her them they it's of to so is are be been being should can could
would will please i we you me us want wish like need just only also too as well very really quite somewhat slightly
bit little lot much much more most make made makes making get gets look looks have has give gives let lets
percent cm mm m inch inches times twice degree degrees by than then same way place position positions where
with on at from for into onto over about around toward towards each both every some one two three few
little far amount possible enough while whilst but and or do does not don dont doesn t no its yet still
now current currently original originally stays size sized own sure evenly even between among
please thanks thank you your honestly hey hi hello ok okay think guess feel feels felt seem seems seemed look looks
looking appear appears want wanted wants would like love prefer ought maybe perhaps probably rather quite actually
basically definitely imo tbh idk lol hmm um uh also now again say says said told
""".split())
#: Negations that turn the verb after them into "keep": ``without moving the legs``, ``don't touch the top``.
NEGATIONS = frozenset({"not", "never", "without", "no"})
#: Verbs a negation may govern besides the edit verbs.
PLAIN_VERBS = frozenset({"change", "alter", "touch", "affect", "modify", "edit", "disturb", "resize"})
#: Counts in words: ``add two more slats``; ``a``/``another`` mean one.
NUMBER_WORDS = {"a": 1, "an": 1, "one": 1, "another": 1, "single": 1, "two": 2, "three": 3, "four": 4, "five": 5,
                "six": 6, "seven": 7, "eight": 8, "nine": 9, "ten": 10, "couple": 2}
CLAUSE_BREAKS = frozenset({"but", "while", "whilst", "by", "with", "then", "so", "although", "though", "except"})
CLAUSE_STARTERS = frozenset({"keeping", "leaving", "without"})
#: Verbs that start a new clause after "and": ``widen the seat and tilt the legs``.
VERB_STARTS = frozenset(set(INTENTS) | set(CHANGE_VERBS) | {"make", "give", "let", "lower", "raise", "also"})

_IRREGULAR = {"feet": "foot", "shelves": "shelf", "leaves": "leaf", "halves": "half", "knives": "knife"}
_KEEP_S = {"its", "this", "is", "was", "has", "does", "as", "us", "less", "across", "apart", "towards",
           "backwards", "forwards", "upwards", "downwards", "outwards", "inwards", "sideways", "always",
           "plus", "chassis", "stays", "rearwards", "frontwards", "leftwards", "rightwards", "afterwards"}


def singular(word: str) -> str:
    """A plural noun's singular (``legs`` -> ``leg``, ``shelves`` -> ``shelf``)."""
    if word in _IRREGULAR:
        return _IRREGULAR[word]
    if word in _KEEP_S or len(word) <= 3:
        return word
    if word.endswith("ies"):
        return word[:-3] + "y"
    if word.endswith(("ches", "shes", "xes", "sses")):
        return word[:-2]
    if word.endswith("s") and not word.endswith("ss"):
        return word[:-1]
    return word


def lemma(word: str) -> str:
    """The base form of a verb the lexicon knows (``tilting`` -> ``tilt``), else the word."""
    if word in INTENTS or word in CHANGE_VERBS:
        return word
    for suffix in ("ing", "ed", "es", "s"):
        if word.endswith(suffix) and len(word) > len(suffix) + 2:
            base = word[: -len(suffix)]
            candidates = [base, base + "e"]
            if len(base) > 2 and base[-1] == base[-2]:
                candidates.append(base[:-1])
            for candidate in candidates:
                if candidate in INTENTS or candidate in CHANGE_VERBS:
                    return candidate
    return word


def tokens(request: str) -> list[str]:
    """Lower-case words; punctuation that separates clauses becomes a ``,`` token."""
    text = request.lower().replace("\u2019", "'")
    text = re.sub(r"\bcan't\b", "can not", text)
    text = re.sub(r"\bwon't\b", "will not", text)
    text = re.sub(r"n't\b", " not", text)
    text = re.sub(r"'(s|d|ll|m|re|ve)\b", "", text)
    text = re.sub(r"\s[-\u2013\u2014]+\s|\.\.+|\u2026", " , ", text)
    text = re.sub(r"[;:!?]", " , ", text)
    text = re.sub(r",", " , ", text)
    text = re.sub(r"(?<!\d)\.|\.(?!\d)", " , ", text)
    text = re.sub(r"[^a-z0-9.,%\s]", " ", text)
    return [t for t in text.split() if t]


def is_number(word: str) -> bool:
    return bool(re.fullmatch(r"\d+(\.\d+)?%?|\d*\.\d+%?|%", word))


def rewrite(words: list[str]) -> list[str]:
    """Chat spellings and idioms replaced by the words they mean (longest phrase first)."""
    words = [SPELLINGS.get(w, w) for w in words]
    longest = max(len(k) for k in IDIOMS)
    out: list[str] = []
    i = 0
    while i < len(words):
        for n in range(min(longest, len(words) - i), 0, -1):
            key = tuple(words[i:i + n])
            if key in IDIOMS:
                out.extend(IDIOMS[key])
                i += n
                break
        else:
            out.append(words[i])
            i += 1
    return out
