"""A rider's weight in kilograms, as the API takes it: a number between 20 and 200 kg.

The range is wide (a child on a pony to a heavy adult) so that only typos and pounds are refused, each
with a sentence saying which.
"""

from __future__ import annotations

import math
from typing import Annotated, Any

from pydantic import AfterValidator, WithJsonSchema

from saddlescope.db.enums import RIDER_WEIGHT_RANGE_KG

__all__ = ["RiderWeightKg", "check_weight_kg"]

LB_KG = 0.45359237


def check_weight_kg(value: float | None) -> float | None:
    """`value` if None or within `RIDER_WEIGHT_RANGE_KG`; ValueError with the reason otherwise."""
    if value is None:
        return None
    low, high = RIDER_WEIGHT_RANGE_KG
    if not math.isfinite(value) or not low <= value <= high:
        hint = ""
        if high < value <= high / LB_KG:
            hint = f" (in pounds? {value:g} lb is {value * LB_KG:.0f} kg)"
        raise ValueError(f"a rider's weight is in kg, between {low:g} and {high:g}; {value:g} is outside{hint}")
    return round(float(value), 1)


def _schema(minimum: float, maximum: float) -> dict[str, Any]:
    return {"anyOf": [{"type": "number", "minimum": minimum, "maximum": maximum}, {"type": "null"}],
            "description": "the rider's weight in kg (20-200); null: not recorded"}


RiderWeightKg = Annotated[
    float | None, AfterValidator(check_weight_kg), WithJsonSchema(_schema(*RIDER_WEIGHT_RANGE_KG))
]
