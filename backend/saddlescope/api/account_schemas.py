"""Bodies of the session routes: a password change, an admin's password reset and its use."""

from __future__ import annotations

import datetime as dt
from typing import Annotated

from pydantic import BaseModel, Field, StringConstraints

from saddlescope.api.schemas import Password, _In

__all__ = ["PasswordChange", "PasswordResetIn", "PasswordResetOut"]


class PasswordChange(_In):
    """The signed-in user's current password and the new one."""

    current_password: Annotated[str, StringConstraints(max_length=1024)]
    new_password: Password


class PasswordResetOut(BaseModel):
    """A one-time reset token for the user, shown once to the admin (no e-mail is sent)."""

    reset_token: str = Field(description="give it to the user; it works once")
    expires_at: dt.datetime
    how: str = Field(description="what the user does with the token")


class PasswordResetIn(_In):
    """A reset token from a club admin and the new password."""

    token: Annotated[str, StringConstraints(min_length=1, max_length=200)]
    new_password: Password
