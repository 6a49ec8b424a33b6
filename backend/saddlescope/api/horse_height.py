"""A horse's height at the withers as a club writes it: metres, centimetres or hands ("15.2 hh").

Hands are the horse world's unit: 1 hand = 4 inches = 0.1016 m, and "15.2" means 15 hands and
2 inches (the digit after the point counts inches, 0-3), not 15.2 hands. The API stores metres.
"""

from __future__ import annotations

import math
import re
from typing import Annotated, Any

from pydantic import BeforeValidator, Field, WithJsonSchema

__all__ = [
    "HAND_M", "HeightWithersM", "INCH_M", "MAX_HEIGHT_M", "MIN_HEIGHT_M", "hands_metres_text", "hands_text",
    "height_in_metres",
]

INCH_M = 0.0254
HAND_M = 4 * INCH_M
MIN_HEIGHT_M, MAX_HEIGHT_M = 0.5, 2.5  # a miniature pony to the tallest draught horse, with room

_HANDS = re.compile(r"^(\d{1,2})(?:[.,](\d))?\s*(?:hh|h|hands?)$", re.IGNORECASE)
_WITH_UNIT = re.compile(r"^(\d+(?:[.,]\d+)?)\s*(cm|m)$", re.IGNORECASE)
_UNITS_HELP = 'write metres (1.62), centimetres ("162 cm") or hands ("15.2 hh")'


def hands_text(height_m: float) -> str:
    """1.5748 -> "15.2 hh" (hands and whole inches)."""
    inches = round(height_m / INCH_M)
    return f"{inches // 4}.{inches % 4} hh"


def _from_hands(hands: str, inches: str | None, text: str) -> float:
    extra = int(inches or 0)
    if extra > 3:
        raise ValueError(f'"{text}": in hands the digit after the point counts inches (0-3), so 15.3 hh is '
                         "followed by 16.0 hh")
    return round((int(hands) * 4 + extra) * INCH_M, 4)


def _parse_text(text: str) -> float:
    compact = text.strip()
    if m := _HANDS.match(compact):
        return _from_hands(m.group(1), m.group(2), compact)
    if m := _WITH_UNIT.match(compact):
        number = float(m.group(1).replace(",", "."))
        return number / 100 if m.group(2).lower() == "cm" else number
    try:
        return float(compact.replace(",", "."))
    except ValueError:
        raise ValueError(f'cannot read "{compact[:40]}" as a height: {_UNITS_HELP}') from None


def height_in_metres(value: Any) -> Any:
    """A height in metres from a number (metres) or a text with its unit; ValueError with the reason.

    None passes (it clears the height); a bare number that can only be hands or centimetres gets a
    reason naming the unit to write; anything else that is not a number or text is left for the
    field's own type check.
    """
    if value is None:
        return value
    if isinstance(value, bool):
        raise ValueError(f"a height must be a number: {_UNITS_HELP}")
    if isinstance(value, str):
        text = value.strip()[:40]
        height_m = _parse_text(text)
        unit_given = not _is_bare_number(text)
    elif isinstance(value, int | float):
        text, height_m, unit_given = f"{value:g}", float(value), False
    else:
        return value
    if not math.isfinite(height_m):
        raise ValueError(f"a height must be a number: {_UNITS_HELP}")
    if not unit_given and 8 <= height_m < 20:
        raise ValueError(f"the height is in metres and {text} m is taller than any horse; for hands write "
                         f'"{text} hh" ({hands_metres_text(text)}), or {_UNITS_HELP}')
    if not unit_given and 50 <= height_m <= 250:
        raise ValueError(f"the height is in metres and {text} m is taller than any horse; for centimetres "
                         f'write "{text} cm", or {_UNITS_HELP}')
    if not MIN_HEIGHT_M < height_m < MAX_HEIGHT_M:
        raise ValueError(f"a horse's height at the withers lies between {MIN_HEIGHT_M} and {MAX_HEIGHT_M} m "
                         f"(got {height_m:g} m): {_UNITS_HELP}")
    return height_m


def _is_bare_number(text: str) -> bool:
    try:
        float(text.replace(",", "."))
    except ValueError:
        return False
    return True


def hands_metres_text(text: str) -> str:
    """Text such as "15.2" read as hands, in metres ("= 1.57 m"), or a hint when it is not valid hands."""
    try:
        return f"= {_parse_text(text + ' hh'):.2f} m"
    except ValueError:
        return "hands and inches 0-3"

# The request field: metres, or a text with its unit; stored and answered in metres.
HeightWithersM = Annotated[
    Annotated[float, Field(gt=MIN_HEIGHT_M, lt=MAX_HEIGHT_M)] | None,
    BeforeValidator(height_in_metres),
    WithJsonSchema({
        "anyOf": [{"type": "number", "exclusiveMinimum": MIN_HEIGHT_M, "exclusiveMaximum": MAX_HEIGHT_M},
                  {"type": "string", "maxLength": 40}, {"type": "null"}],
        "description": 'height at the withers in metres (1.62), or with its unit: "162 cm", "15.2 hh" (hands)',
    }),
]
