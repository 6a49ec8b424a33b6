"""`saddlescope serve`: uvicorn running the application of `saddlescope.api.create_app`."""

from __future__ import annotations

import errno
import socket

from saddlescope.settings import Settings, get_settings

__all__ = ["KEEP_ALIVE_S", "PortInUse", "check_port_free", "serve"]

KEEP_ALIVE_S = 75  # seconds an idle keep-alive connection stays open (uvicorn's default: 5)


class PortInUse(Exception):
    """The address to serve on is taken: its message is one plain sentence saying how to pick another."""


def check_port_free(host: str, port: int, *, hint: str = "saddlescope serve --port {port}") -> None:
    """Raise `PortInUse` (one plain sentence: which port, how to choose another) when `host:port` is taken.

    Bound the way uvicorn binds (address reuse on), so a port only in TIME_WAIT counts as free.
    """
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as exc:
            if exc.errno not in (errno.EADDRINUSE, errno.EACCES):
                raise
            why = "is already in use (is SaddleScope already running?)" if exc.errno == errno.EADDRINUSE \
                else "may not be used by this user"
            raise PortInUse(f"port {port} on {host} {why}: stop the program using it, or pick another port, "
                            f"e.g. {hint.format(port=port + 1)}") from None


def serve(host: str = "127.0.0.1", port: int = 8000, *, settings: Settings | None = None) -> None:
    """Serve the API and the dashboard until interrupted (one process; jobs per the settings)."""
    import uvicorn

    # Imported here: the web layer sits above the services (only this entry point needs it).
    from saddlescope.api.app import create_app

    check_port_free(host, port)
    settings = settings or get_settings()
    app = create_app(settings)
    # A client or proxy that reuses its pooled connection just as the server closes it gets a reset (seen
    # from Playwright's request client after a 5 s pause); idle connections kept longer make that rare.
    uvicorn.run(app, host=host, port=port, log_level="info", proxy_headers=True,
                forwarded_allow_ips=settings.forwarded_allow_ips, timeout_graceful_shutdown=10,
                timeout_keep_alive=KEEP_ALIVE_S)
