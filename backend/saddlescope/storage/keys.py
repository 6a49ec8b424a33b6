"""Storage keys: where each kind of file lives, the same in every back end.

A *key* is a relative POSIX path such as ``rides/12/bundle/motion/left.mp4``; the database stores
keys, never paths or URLs, so the storage can move between folders and buckets.
"""

from __future__ import annotations

import secrets

__all__ = [
    "direct_upload_key", "rig_stage_output_key", "ride_bundle_key", "stage_output_key", "upload_chunk_key",
    "upload_key",
]


def ride_bundle_key(ride_id: int) -> str:
    """The key of ride `ride_id`'s uploaded bundle."""
    return f"rides/{ride_id}/bundle"


def stage_output_key(ride_id: int, stage: str) -> str:
    """The folder a pipeline stage owns for one ride; re-running the stage replaces it."""
    return f"rides/{ride_id}/stages/{stage}"


def rig_stage_output_key(rig_id: int, stage: str) -> str:
    """The folder a stage of a rig's job owns (e.g. its calibration)."""
    return f"rigs/{rig_id}/stages/{stage}"


def upload_key(upload_id: str) -> str:
    """Where the bytes of a resumable upload collect until it is finalised."""
    return f"uploads/{upload_id}.part"


def upload_chunk_key(upload_id: str) -> str:
    """A fresh key for one PATCH's bytes of a resumable upload, before they are checked and appended."""
    return f"uploads/{upload_id}.chunk-{secrets.token_hex(8)}"


def direct_upload_key(upload_id: str) -> str:
    """The object a direct upload's parts (sent by the client straight to the bucket) become."""
    return f"uploads/{upload_id}.direct"
