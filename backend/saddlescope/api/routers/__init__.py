"""One router per resource (each module's `router`); `common` and `clips` hold what several of them share."""

__all__ = [
    "auth", "clips", "common", "comparisons", "grades", "health", "horse_profile", "horses", "jobs", "mocap",
    "riders", "rides",
    "rigs", "similarity", "uploads",
]
