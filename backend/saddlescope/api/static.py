"""The dashboard's files, with cache headers that keep a page load to a few small requests.

`vendor/` holds pinned, versioned libraries (the file name carries the version, e.g.
``plotly-3.7.0.min.js``), so a browser may keep them for a year without asking again. Everything else
(index.html, app.js, the page modules and the markup beside them, style.css) changes with each release under
the same name: the browser keeps it but revalidates each load (``no-cache``), answered 304 from the ETag
when unchanged.
"""

from __future__ import annotations

from starlette.responses import Response
from starlette.staticfiles import StaticFiles
from starlette.types import Scope

__all__ = ["DashboardFiles"]

IMMUTABLE = "public, max-age=31536000, immutable"
REVALIDATE = "no-cache"


class DashboardFiles(StaticFiles):
    """`StaticFiles` that sets ``Cache-Control`` by folder (see the module's docstring)."""

    async def get_response(self, path: str, scope: Scope) -> Response:
        """Return the file's response with its ``Cache-Control`` header."""
        response = await super().get_response(path, scope)
        if response.status_code in (200, 304):
            response.headers["Cache-Control"] = IMMUTABLE if path.startswith("vendor/") else REVALIDATE
        return response
