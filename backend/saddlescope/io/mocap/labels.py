"""Marker labels matched between two files: the same body landmark under another marker set's name.

Labs name one landmark many ways: Plug-in-Gait ``RASI``, BTK's ``R.ASIS``, ``RightASIS``, ``R_ASIS``.
A label is reduced to a key (side, landmark) by one table of common aliases (:data:`LANDMARK_ALIASES`);
two labels match when their keys do. A repeated C3D label told apart by its description
(``"RKNE (R.Knee.Medial)"``) is keyed by the description. A user mapping (``A=B``) comes first.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from saddlescope.core.errors import InputError

__all__ = ["LANDMARK_ALIASES", "LabelMatch", "landmark_key", "match_labels", "parse_label_map"]

# Landmark (Plug-in-Gait's code without the side letter) -> its other names, written lower case
# without separators. Sided landmarks take a side prefix (R, L, Right, Left; with ".", "_", " ", "-"
# or nothing between); midline ones have none.
LANDMARK_ALIASES: dict[str, tuple[str, ...]] = {
    "ASI": ("asi", "asis", "antsupiliacspine", "anteriorsuperioriliacspine", "iliacspine"),
    "PSI": ("psi", "psis", "postsupiliacspine", "posteriorsuperioriliacspine"),
    "SHO": ("sho", "shoulder", "acromion", "should"),
    "ELB": ("elb", "elbow", "elbowlateral", "lateralelbow"),
    "WRI": ("wri", "wrist", "wra"),
    "THI": ("thi", "thigh", "thighwand"),
    "KNE": ("kne", "knee", "kneelateral", "lateralknee", "lfe", "kneelat"),
    "KNM": ("knm", "kneemedial", "medialknee", "mkne", "kneemed", "mfe"),
    "TIB": ("tib", "shank", "sha", "tibia", "shankwand", "tibiawand"),
    "ANK": ("ank", "ankle", "anklelateral", "lateralankle", "lateralmalleolus", "lmal", "ankl"),
    "MED": ("med", "anklemedial", "medialankle", "medialmalleolus", "mmal", "mma"),
    "HEE": ("hee", "heel", "calcaneus", "cal"),
    "TOE": ("toe", "toes", "toetip", "met2", "secondmetatarsalhead", "mt2"),
    "OFF": ("off", "offset"),
    "SACR": ("sacr", "sacrum", "sacral", "vsacral", "vsac", "sac"),
    "C7": ("c7", "cervical7"),
    "T10": ("t10", "thoracic10"),
    "CLAV": ("clav", "ij", "jugularnotch", "incisurajugularis", "clavicle", "manubrium"),
    "STRN": ("strn", "px", "sternum", "xiphoid", "processusxiphoideus"),
}
_MIDLINE = {"SACR", "C7", "T10", "CLAV", "STRN"}
_ALIAS_TO_LANDMARK = {alias: code for code, names in LANDMARK_ALIASES.items() for alias in names}
_SIDES = (("right", "R"), ("left", "L"), ("r", "R"), ("l", "L"))


def _squash(text: str) -> str:
    return re.sub(r"[^a-z0-9]", "", text.lower())


def landmark_key(label: str) -> str:
    """The label's landmark key, e.g. ``"R:ASI"`` for RASI, R.ASIS, RightASIS; ``"C7"`` midline.

    A label the table does not know keys as itself (squashed to lower-case letters and digits), so
    identical unknown labels still match.
    """
    inner = re.fullmatch(r".+? \((.+)\)", label.strip())
    text = inner.group(1) if inner else label
    squashed = _squash(text)
    code = _ALIAS_TO_LANDMARK.get(squashed)
    if code in _MIDLINE:
        return code
    for word, side in _SIDES:
        if squashed.startswith(word):
            rest = _ALIAS_TO_LANDMARK.get(squashed[len(word):])
            if rest is not None and rest not in _MIDLINE:
                return f"{side}:{rest}"
    for word, side in (("right", "R"), ("left", "L")):  # "ASISRight", "knee_left"
        if squashed.endswith(word):
            rest = _ALIAS_TO_LANDMARK.get(squashed[: -len(word)])
            if rest is not None and rest not in _MIDLINE:
                return f"{side}:{rest}"
    return "=" + squashed


@dataclass(frozen=True)
class LabelMatch:
    """Labels of file A paired with labels of file B.

    Attributes
    ----------
    pairs : tuple of (str, str)
        (label in A, label in B), in A's order.
    unmatched_a, unmatched_b : tuple of str
        Labels of either file with no partner.
    by_alias : tuple of (str, str)
        The pairs found through :data:`LANDMARK_ALIASES` (not the same label, not the user's map).
    """

    pairs: tuple[tuple[str, str], ...]
    unmatched_a: tuple[str, ...]
    unmatched_b: tuple[str, ...]
    by_alias: tuple[tuple[str, str], ...]


def parse_label_map(items: Sequence[str] | None) -> dict[str, str]:
    """``["A=B", ...]`` (a label of the first file = a label of the second) as a dict."""
    out: dict[str, str] = {}
    for item in items or ():
        a, sep, b = item.partition("=")
        if not sep or not a.strip() or not b.strip():
            raise InputError(f"a label mapping must look like LABEL_IN_A=LABEL_IN_B, got {item!r}")
        out[a.strip()] = b.strip()
    return out


def match_labels(labels_a: Sequence[str], labels_b: Sequence[str], *, user_map: Mapping[str, str] | None = None,
                 wanted: Sequence[str] | None = None) -> LabelMatch:
    """Pair A's labels with B's: the user's map, then the same label, then the same landmark key.

    Parameters
    ----------
    labels_a, labels_b : sequence of str
        The two files' labels.
    user_map : mapping, optional
        Label in A -> label in B, taken first.
    wanted : sequence of str, optional
        Only these labels of A (``--markers``).

    Raises
    ------
    InputError
        A mapped or wanted label one file does not have.
    """
    user_map = dict(user_map or {})
    for a, b in user_map.items():
        if a not in labels_a:
            raise InputError(f"--map {a}={b}: the first file has no marker labelled {a!r}")
        if b not in labels_b:
            raise InputError(f"--map {a}={b}: the second file has no marker labelled {b!r}")
    chosen = list(wanted) if wanted else list(labels_a)
    missing = [s for s in chosen if s not in labels_a]
    if missing:
        raise InputError(f"the first file has no marker labelled {', '.join(missing)}; it has "
                         f"{', '.join(list(labels_a)[:12])}")
    free_b = [s for s in labels_b if s not in user_map.values()]
    keys_b: dict[str, str] = {}
    for s in free_b:
        keys_b.setdefault(landmark_key(s), s)
    pairs, by_alias, unmatched = [], [], []
    for a in chosen:
        if a in user_map:
            pairs.append((a, user_map[a]))
        elif a in free_b:
            pairs.append((a, a))
        elif (alias := keys_b.get(landmark_key(a))) is not None and alias not in {p[1] for p in pairs}:
            pairs.append((a, alias))
            by_alias.append((a, alias))
        else:
            unmatched.append(a)
    used_b = {p[1] for p in pairs}
    return LabelMatch(pairs=tuple(pairs), unmatched_a=tuple(unmatched),
                      unmatched_b=tuple(s for s in labels_b if s not in used_b), by_alias=tuple(by_alias))
