"""Create the bucket of SADDLESCOPE_STORAGE_URL if it does not exist (the compose file's one-shot `migrate`)."""

from __future__ import annotations

import sys

from saddlescope.settings import get_settings
from saddlescope.storage.s3 import S3Storage


def main() -> int:
    """Make the bucket once; 0 when it is there (made now or before)."""
    settings = get_settings()
    url = settings.storage_url or ""
    if not url.startswith("s3://"):
        print(f"SADDLESCOPE_STORAGE_URL is {url!r}, not s3://...: no bucket to make")
        return 0
    storage = S3Storage.from_url(url, endpoint_url=settings.s3_endpoint_url)
    existing = {b["Name"] for b in storage.client.list_buckets().get("Buckets", [])}
    if storage.bucket not in existing:
        storage.client.create_bucket(Bucket=storage.bucket)
        print(f"made bucket {storage.bucket}")
    else:
        print(f"bucket {storage.bucket} is there")
    return 0


if __name__ == "__main__":
    sys.exit(main())
