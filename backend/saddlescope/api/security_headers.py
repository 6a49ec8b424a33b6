"""Browser security headers on every response: the API's, the dashboard's files, the reports, the errors.

The Content-Security-Policy lets a page run only the app's own scripts and styles: no inline script, no
eval, no style element but Plotly's two (by hash); style attributes, which Plotly's charts need, run
nothing. A page talks only to this server (and the object store, for direct uploads) and is never shown
in a frame (with X-Frame-Options for older browsers). A response that sets its own policy keeps it (the
ride report allows its one inline style by hash; ``/docs`` the Swagger UI). deploy/haproxy.cfg sets the
same headers at the proxy.
"""

from __future__ import annotations

import base64
import hashlib
import re
from urllib.parse import urlsplit

from starlette.types import ASGIApp, Message, Receive, Scope, Send

__all__ = ["DOCS_CSP", "SecurityHeaders", "content_security_policy", "inline_style_hashes", "report_csp"]

# The Swagger UI of /docs is FastAPI's page: its script and styles come from jsDelivr, with one inline script.
DOCS_PATHS = ("/docs", "/docs/oauth2-redirect")
DOCS_CSP = ("default-src 'self'; script-src 'self' 'unsafe-inline' https://cdn.jsdelivr.net; "
            "style-src 'self' https://cdn.jsdelivr.net; img-src 'self' data: https://fastapi.tiangolo.com; "
            "connect-src 'self'; object-src 'none'; base-uri 'self'; frame-ancestors 'none'")


def _origin(url: str | None) -> str | None:
    if not url:
        return None
    parts = urlsplit(url)
    return f"{parts.scheme}://{parts.netloc}" if parts.scheme and parts.netloc else None


# The vendored Plotly (frontend/vendor, pinned) adds <style> elements with these exact contents (an empty
# one, then its global rules), and positions a chart's parts with style attributes. Style attributes can
# run no script and hold no selector, so they are allowed; style elements only with Plotly's hashes.
PLOTLY_STYLE_HASHES = ("'sha256-47DEQpj8HBSa+/TImW+5JCeuQeRkm5NMpJWZG3hSuFU='",
                       "'sha256-V2sIX92Uh6ZaGSFTKMHghsB85b9toJtmazgG09AI2uk='")


def content_security_policy(*, upload_origin: str | None = None) -> str:
    """The dashboard's policy; `upload_origin`: the object store the browser PUTs upload parts to."""
    connect = " ".join(filter(None, ("'self'", upload_origin)))
    return ("default-src 'self'; script-src 'self'; style-src 'self'; "
            f"style-src-elem 'self' {' '.join(PLOTLY_STYLE_HASHES)}; style-src-attr 'unsafe-inline'; "
            "img-src 'self' data: blob:; "
            f"font-src 'self'; connect-src {connect}; worker-src 'self' blob:; object-src 'none'; "
            "base-uri 'self'; form-action 'self'; frame-ancestors 'none'")


INLINE_STYLE = re.compile(r"<style>(.*?)</style>", re.S)


def inline_style_hashes(page: str) -> list[str]:
    """CSP source of each inline <style> of a self-contained print page (the ride report, the board)."""
    return ["sha256-" + base64.b64encode(hashlib.sha256(css.encode()).digest()).decode()
            for css in INLINE_STYLE.findall(page)]


def report_csp(style_hashes: list[str]) -> str:
    """The ride report's policy: no script at all, its own inline style by hash (`'sha256-...'`)."""
    styles = " ".join(f"'{h}'" for h in style_hashes)
    return (f"default-src 'none'; style-src {styles}; img-src 'self' data:; base-uri 'none'; "
            "form-action 'none'; frame-ancestors 'none'")


def headers_for(settings) -> list[tuple[bytes, bytes]]:
    """The headers every response gets (the CSP knows the object store's address for direct uploads)."""
    upload_origin = None
    if settings.storage_url and settings.storage_url.startswith("s3://"):
        upload_origin = _origin(settings.s3_public_endpoint_url or settings.s3_endpoint_url)
    return [
        (b"content-security-policy", content_security_policy(upload_origin=upload_origin).encode()),
        (b"x-frame-options", b"DENY"),
        (b"x-content-type-options", b"nosniff"),
        (b"referrer-policy", b"same-origin"),
        (b"permissions-policy", b"camera=(), microphone=(), geolocation=(), payment=(), usb=()"),
        (b"cross-origin-opener-policy", b"same-origin"),
    ]


class SecurityHeaders:
    """ASGI middleware adding `headers_for(settings)` to every HTTP response that lacks them."""

    def __init__(self, app: ASGIApp, settings) -> None:
        self.app = app
        self.headers = headers_for(settings)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        """Pass the request on; add the headers to the response's start."""
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        docs = scope.get("path") in DOCS_PATHS

        async def send_with_headers(message: Message) -> None:
            if message["type"] == "http.response.start":
                headers = list(message.get("headers", []))
                present = {name.lower() for name, _ in headers}
                for name, value in self.headers:
                    if name == b"content-security-policy" and docs:
                        value = DOCS_CSP.encode()
                    if name not in present:
                        headers.append((name, value))
                message = {**message, "headers": headers}
            await send(message)

        await self.app(scope, receive, send_with_headers)
