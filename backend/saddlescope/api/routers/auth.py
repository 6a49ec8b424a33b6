"""Accounts: register a club, sign in and out (bearer token + session cookie), the caller, club users."""

from __future__ import annotations

import json

from fastapi import APIRouter, Request, Response, status
from pydantic import ValidationError
from starlette.concurrency import run_in_threadpool

from saddlescope.api.account_schemas import PasswordChange, PasswordResetIn, PasswordResetOut
from saddlescope.api.deps import (
    CSRF_COOKIE,
    SESSION_COOKIE,
    AdminClubDep,
    ClubDep,
    OptionalBearerDep,
    SessionDep,
    SessionFactoryDep,
    SettingsDep,
    check_csrf,
    client_address,
)
from saddlescope.api.routers.common import CONFLICT, ERRORS, Id, PagingDep, page_of
from saddlescope.api.schemas import (
    ClubCreate,
    ClubCreated,
    ClubOut,
    ErrorOut,
    LoginIn,
    MeOut,
    Page,
    TokenOut,
    UserCreate,
    UserOut,
    UserUpdate,
)
from saddlescope.core.errors import InputError
from saddlescope.db.repositories import ClubRepository
from saddlescope.db.session import session_scope
from saddlescope.services.accounts.permissions import grants
from saddlescope.services.accounts.users import (
    AuthError,
    Forbidden,
    WrongPassword,
    add_user,
    authenticate,
    change_password,
    consume_password_reset,
    create_club,
    end_sessions,
    end_sign_in,
    issue_token,
    read_token,
    start_password_reset,
    update_user,
)

__all__ = ["LOGIN_OPENAPI", "registration_open", "router"]

router = APIRouter(tags=["accounts"])

LOGIN_OPENAPI = {
    "requestBody": {
        "required": True,
        "content": {
            "application/x-www-form-urlencoded": {
                "schema": {
                    "type": "object",
                    "required": ["username", "password"],
                    "properties": {
                        "username": {"type": "string", "description": "e-mail address"},
                        "password": {"type": "string", "format": "password"},
                    },
                }
            },
            "application/json": {"schema": LoginIn.model_json_schema()},
        },
    }
}


def registration_open(request: Request, sessions) -> bool:
    """Embedded mode, a first club, or ``open_registration``: anyone may create a club."""
    configured = getattr(request.app.state, "open_registration", None)
    if configured is not None:
        return bool(configured)
    if request.app.state.settings.embedded:
        return True
    with session_scope(sessions) as session:
        return ClubRepository(session).count() == 0


@router.post(
    "/clubs",
    status_code=status.HTTP_201_CREATED,
    response_model=ClubCreated,
    responses={403: {"model": ErrorOut}, 422: {"model": ErrorOut}, 503: {"model": ErrorOut}, **CONFLICT},
)
async def register_club(body: ClubCreate, request: Request, sessions: SessionFactoryDep) -> ClubCreated:
    """Create a club and its first user, an admin.

    Open in embedded mode (no broker: a laptop or a club's own small server) and for the first club
    of a deployment; closed otherwise unless the server was started with open registration.
    """

    def create() -> ClubCreated:
        if not registration_open(request, sessions):
            raise Forbidden("registration of new clubs is closed on this server; ask its operator")
        with session_scope(sessions) as session:
            club, user = create_club(
                session,
                club_name=body.club_name,
                email=body.email,
                password=body.password,
                display_name=body.display_name,
            )
            return ClubCreated(club=ClubOut.model_validate(club), user=UserOut.model_validate(user))

    return await request.app.state.hash_pool.run(create)  # Argon2 in its bounded pool (a public route)


async def _credentials(request: Request) -> tuple[str, str]:
    content_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if content_type == "application/json":
        try:
            body = LoginIn.model_validate(json.loads(await request.body() or b"null"))
        except (ValueError, ValidationError) as exc:
            raise InputError(f'sign-in needs {{"email", "password"}} ({str(exc).splitlines()[0]})') from None
        return body.email, body.password
    form = await request.form(max_files=0, max_fields=10)
    username, password = form.get("username"), form.get("password")
    if not isinstance(username, str) or not isinstance(password, str) or not username:
        raise InputError("sign-in needs the form fields username (your e-mail address) and password")
    if "\x00" in username or "\x00" in password:
        raise InputError("the e-mail address or password contains a NUL character")
    return username, password


def cookie_secure(request: Request, settings) -> bool:
    """The cookies' Secure flag: the setting, or (auto) whether the request came over https.

    The scheme is the one uvicorn settled after the forwarded headers of the trusted proxies
    (``SADDLESCOPE_FORWARDED_ALLOW_IPS``), so a proxy on another host works too.
    """
    choice = getattr(settings, "cookie_secure", "auto")
    if choice != "auto":
        return choice == "true"
    return request.url.scheme == "https"


@router.post(
    "/auth/login",
    response_model=TokenOut,
    openapi_extra=LOGIN_OPENAPI,
    responses={401: {"model": ErrorOut}, 422: {"model": ErrorOut}, 429: {"model": ErrorOut},
               503: {"model": ErrorOut}},
)
async def login(
    request: Request, response: Response, settings: SettingsDep, sessions: SessionFactoryDep
) -> TokenOut:
    """Sign in with e-mail and password (OAuth2 password form, or JSON).

    Returns a bearer token and sets the session cookie (HttpOnly) and the CSRF cookie for the browser.
    """
    email, password = await _credentials(request)
    guard = request.app.state.login_guard
    address = client_address(request)
    # Refused before the password is even looked at: the right password is no help while locked out.
    await run_in_threadpool(guard.check, email, address)

    def check() -> TokenOut:
        with session_scope(sessions) as session:
            user = authenticate(session, email, password)
            token, csrf, lifetime_s = issue_token(user, settings)
            return TokenOut(
                access_token=token, expires_in=lifetime_s, csrf_token=csrf, user=UserOut.model_validate(user)
            )

    try:
        out = await request.app.state.hash_pool.run(check)  # Argon2: its own bounded pool
    except AuthError:
        await run_in_threadpool(guard.failed, email, address)
        raise
    await run_in_threadpool(guard.succeeded, email, address)
    secure = cookie_secure(request, settings)
    response.set_cookie(
        SESSION_COOKIE,
        out.access_token,
        max_age=out.expires_in,
        httponly=True,
        secure=secure,
        samesite="lax",
        path="/",
    )
    response.set_cookie(
        CSRF_COOKIE,
        out.csrf_token,
        max_age=out.expires_in,
        httponly=False,
        secure=secure,
        samesite="lax",
        path="/",
    )
    return out


@router.post("/auth/logout", status_code=status.HTTP_204_NO_CONTENT,
             responses={403: {"model": ErrorOut, "description": "signed in by the cookie, without the CSRF header"}})
def logout(request: Request, response: Response, settings: SettingsDep, session: SessionDep,
           bearer: OptionalBearerDep) -> Response:
    """Sign out: this sign-in's token is refused from now on, and the browser's cookies are cleared.

    The bearer token and the browser's cookie of one sign-in are the same token: both end. Other sign-ins
    of the user go on (logout-everywhere ends them). By the cookie it needs the CSRF header, as every state
    change does; a missing, expired or invalid token has nothing to end (the cookies are cleared anyway).
    """
    token = bearer or request.cookies.get(SESSION_COOKIE)
    try:
        principal = read_token(token, settings) if token else None
    except AuthError:
        principal = None
    if principal is not None:
        if not bearer:
            check_csrf(request, principal)
        end_sign_in(session, principal)
    return _forget_browser(response)


def _forget_browser(response: Response) -> Response:
    response.delete_cookie(SESSION_COOKIE, path="/")
    response.delete_cookie(CSRF_COOKIE, path="/")
    response.status_code = status.HTTP_204_NO_CONTENT
    return response


@router.post("/auth/logout-everywhere", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
def logout_everywhere(club: ClubDep, response: Response) -> Response:
    """End every session of the signed-in user (all browsers and bearer tokens); sign in again after."""
    end_sessions(club.users.get(club.principal.user_id))
    return _forget_browser(response)


@router.post("/auth/password", status_code=status.HTTP_204_NO_CONTENT, responses=ERRORS)
async def change_own_password(
    body: PasswordChange, club: ClubDep, request: Request, response: Response
) -> Response:
    """Change your own password (the current one is needed); every session ends, sign in again.

    A wrong current password counts as a failed sign-in (a stolen session cannot guess it unhindered).
    """
    guard = request.app.state.login_guard
    email = (await run_in_threadpool(club.users.get, club.principal.user_id)).email
    address = client_address(request)
    await run_in_threadpool(guard.check, email, address)
    try:
        await request.app.state.hash_pool.run(  # Argon2 verify + hash: its bounded pool
            lambda: change_password(club.session, user_id=club.principal.user_id,
                                    current_password=body.current_password, new_password=body.new_password))
    except WrongPassword:
        await run_in_threadpool(guard.failed, email, address)
        raise
    return _forget_browser(response)


@router.post("/users/{user_id}/password-reset", status_code=status.HTTP_201_CREATED,
             response_model=PasswordResetOut, responses=ERRORS)
def reset_password(user_id: Id, club: AdminClubDep) -> PasswordResetOut:
    """Reset a user's password (admins only): their sessions end and their old password stops working.

    The answer holds a one-time token, shown only now, for the admin to hand to the user (no e-mail is
    sent); it sets a new password through ``POST /api/auth/password-reset`` within 24 hours.
    """
    token, expires_at = start_password_reset(club.session, club_id=club.club_id, user_id=user_id)
    return PasswordResetOut(
        reset_token=token, expires_at=expires_at,
        how='POST /api/auth/password-reset with {"token": "<this token>", "new_password": "..."}')


@router.post("/auth/password-reset", status_code=status.HTTP_204_NO_CONTENT,
             responses={401: {"model": ErrorOut}, 422: {"model": ErrorOut}})
async def use_password_reset(
    body: PasswordResetIn, request: Request, sessions: SessionFactoryDep, response: Response
) -> Response:
    """Set a new password with the one-time token a club admin issued; then sign in with it."""

    def consume() -> None:
        with session_scope(sessions) as session:
            consume_password_reset(session, token=body.token, new_password=body.new_password)

    await request.app.state.hash_pool.run(consume)  # Argon2 in its bounded pool (a public route)
    return _forget_browser(response)


@router.get("/auth/me", response_model=MeOut, responses=ERRORS)
def me(club: ClubDep) -> MeOut:
    """The signed-in user and their club."""
    user = club.users.get(club.principal.user_id)
    return MeOut(user=UserOut.model_validate(user), club=ClubOut.model_validate(user.club),
                 permissions=grants(club.principal))


@router.get("/users", response_model=Page[UserOut], responses=ERRORS)
def list_users(club: AdminClubDep, paging: PagingDep) -> dict:
    """The club's users (admins only)."""
    page = club.users.list_page(sort=paging.sort, limit=paging.limit, offset=paging.offset)
    return page_of(page, UserOut.model_validate)


@router.post(
    "/users", status_code=status.HTTP_201_CREATED, response_model=UserOut, responses={**ERRORS, **CONFLICT}
)
async def create_user(body: UserCreate, club: AdminClubDep, request: Request) -> UserOut:
    """Add a user to the club (admins only); they sign in with this e-mail and password."""
    user = await request.app.state.hash_pool.run(  # Argon2: its bounded pool, not the request threads
        lambda: add_user(club.session, club_id=club.club_id, email=body.email, password=body.password,
                         display_name=body.display_name, role=body.role))
    return UserOut.model_validate(user)


@router.get("/users/{user_id}", response_model=UserOut, responses=ERRORS)
def read_user(user_id: Id, club: AdminClubDep) -> UserOut:
    """A user of the club (admins only)."""
    return UserOut.model_validate(club.users.get(user_id))


@router.patch("/users/{user_id}", response_model=UserOut, responses={**ERRORS, **CONFLICT})
async def change_user(user_id: Id, body: UserUpdate, club: AdminClubDep, request: Request) -> UserOut:
    """Change a user's role, name or password, or deactivate them (admins only; one admin always stays)."""
    changes = body.model_dump(exclude_unset=True)
    # A new password means Argon2: its bounded pool; other changes stay on the request threads.
    run = request.app.state.hash_pool.run if changes.get("password") is not None else run_in_threadpool
    user = await run(lambda: update_user(club.session, club_id=club.club_id, user_id=user_id, **changes))
    return UserOut.model_validate(user)
