"""What a club's members may do: one table, shown in docs/permissions.md and enforced through `require`.

A rule is ``"member"`` (any signed-in user of the club), ``"owner"`` (an admin, or the member who made the
thing: the ride, or the ride a job works on) or ``"admin"`` (club admins only). A test reads the table
in docs/permissions.md and compares it with `PERMISSIONS`, so the page and the code cannot drift apart.
"""

from __future__ import annotations

from saddlescope.services.accounts.users import Forbidden, Principal

__all__ = ["ADMIN", "MEMBER", "OWNER", "PERMISSIONS", "allowed", "grants", "require"]

MEMBER, OWNER, ADMIN = "member", "owner", "admin"

# action: (who may, what it is)
PERMISSIONS: dict[str, tuple[str, str]] = {
    "ride.create": (MEMBER, "add a ride (by form, by clips, by a bundle or a motion-capture file)"),
    "ride.upload_clip": (MEMBER, "upload or replace a clip of a ride"),
    "ride.analyse": (MEMBER, "start a job on a ride (probe, analyze) or a rig"),
    "ride.delete": (OWNER, "delete a ride with its clips, jobs, result and grades"),
    "job.cancel": (OWNER, "cancel a job (its ride's owner; jobs without a ride: admins)"),
    "job.retry": (OWNER, "retry a failed or cancelled job (its ride's owner; jobs without a ride: admins)"),
    "job.selftest": (ADMIN, "start a selftest job"),
    "grade.create": (MEMBER, "grade a ride"),
    "horse.create": (MEMBER, "add or rename a horse or a rider"),
    "horse.delete": (ADMIN, "delete a horse or a rider"),
    "saddle.create": (MEMBER, "add or change a saddle of the club"),
    "saddle.delete": (ADMIN, "delete a saddle no ride uses"),
    "rig.create": (MEMBER, "add a rig and upload its calibration clips"),
    "rig.change_board": (ADMIN, "change a rig's calibration board"),
    "rig.delete": (ADMIN, "delete a rig"),
    "user.manage": (ADMIN, "list, add and change the club's users and their roles"),
    "share.create": (MEMBER, "make a read-only link to a ride's report or a horse's page for a vet"),
    "share.manage": (ADMIN, "list the club's share links and withdraw one"),
}


def allowed(principal: Principal, action: str, *, owner_id: int | None = None) -> bool:
    """Whether `principal` may do `action` (on a thing made by user `owner_id`, for "owner" rules)."""
    rule = PERMISSIONS[action][0]
    if rule == MEMBER or principal.is_admin:
        return True
    return rule == OWNER and owner_id is not None and owner_id == principal.user_id


def grants(principal: Principal) -> dict[str, str]:
    """Per action what `principal` may do: "all", "own" (only what they made) or "none"."""
    out = {}
    for action, (rule, _what) in PERMISSIONS.items():
        if rule == MEMBER or principal.is_admin:
            out[action] = "all"
        else:
            out[action] = "own" if rule == OWNER else "none"
    return out


def require(principal: Principal, action: str, *, owner_id: int | None = None) -> None:
    """Raise `Forbidden` (403) naming the action unless `principal` may do it."""
    if not allowed(principal, action, owner_id=owner_id):
        rule, what = PERMISSIONS[action]
        who = "a club admin" if rule == ADMIN else "a club admin or the member who made it"
        raise Forbidden(f"only {who} may {what} ({action}; see docs/permissions.md)")
