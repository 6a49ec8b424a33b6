"""Celery workers of SaddleScope: thin tasks that call `saddlescope.services`."""
