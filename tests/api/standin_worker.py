"""A Celery worker app with the stand-in analysis installed (``celery -A standin_worker worker``).

Started by the API tests with ``PYTHONPATH`` holding tests/ and tests/api/; the tasks and settings are
SaddleScope's own, only the analysis and the rig calibration are the fast stand-ins of `api_helpers`.
"""

import api_helpers

api_helpers.install_standin()

from saddlescope_worker.app import app  # noqa: E402  (after the stand-ins are in place)

__all__ = ["app"]
