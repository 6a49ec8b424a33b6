"""Dependencies of the routes, as ``Annotated`` aliases (one place to change how each is made)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends, Request
from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker

from saddlescope.db.session import session_scope
from saddlescope.jobs import JobQueue
from saddlescope.settings import Settings
from saddlescope.storage import Storage


def _settings(request: Request) -> Settings:
    return request.app.state.settings


def _engine(request: Request) -> Engine:
    return request.app.state.engine


def _sessions(request: Request) -> sessionmaker[Session]:
    return request.app.state.sessions


def _session(request: Request) -> Iterator[Session]:
    # Commits when the route returns normally; routes that enqueue work commit first themselves.
    with session_scope(request.app.state.sessions) as session:
        yield session


def _storage(request: Request) -> Storage:
    return request.app.state.storage


def _queue(request: Request) -> JobQueue:
    return request.app.state.queue


SettingsDep = Annotated[Settings, Depends(_settings)]
EngineDep = Annotated[Engine, Depends(_engine)]
SessionFactoryDep = Annotated[sessionmaker[Session], Depends(_sessions)]
SessionDep = Annotated[Session, Depends(_session)]
StorageDep = Annotated[Storage, Depends(_storage)]
QueueDep = Annotated[JobQueue, Depends(_queue)]
