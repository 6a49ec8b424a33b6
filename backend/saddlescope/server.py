"""`saddlescope serve`: uvicorn running the application of `saddlescope.api.create_app`."""

from __future__ import annotations

from saddlescope.settings import Settings, get_settings

KEEP_ALIVE_S = 75  # seconds an idle keep-alive connection stays open (uvicorn's default: 5)


def serve(host: str = "127.0.0.1", port: int = 8000, *, settings: Settings | None = None) -> None:
    """Serve the API and the dashboard until interrupted (one process; jobs per the settings)."""
    import uvicorn

    # Imported here: the web layer sits above the services (only this entry point needs it).
    from saddlescope.api.app import create_app

    settings = settings or get_settings()
    app = create_app(settings)
    # A client or proxy that reuses its pooled connection just as the server closes it gets a reset (seen
    # from Playwright's request client after a 5 s pause); idle connections kept longer make that rare.
    uvicorn.run(app, host=host, port=port, log_level="info", proxy_headers=True,
                forwarded_allow_ips=settings.forwarded_allow_ips, timeout_graceful_shutdown=10,
                timeout_keep_alive=KEEP_ALIVE_S)
