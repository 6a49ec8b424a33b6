"""Uploads: clips, ride bundles and resumable uploads accepted, probed and turned into work."""
