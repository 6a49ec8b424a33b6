// Who is signed in: asks /api/auth/me once at start, keeps the answer, and tells listeners on change.

import { ApiError, get, onUnauthorised, post, setCsrfToken } from "./api.js";

/** @typedef {import("./api-types").MeOut} MeOut */
/** @typedef {(current: MeOut | null) => void} SessionListener */

/** @type {MeOut | null} */
let current = null; // {user, club, permissions} or null
/** @type {Set<SessionListener>} */
const listeners = new Set();

function changed() {
  for (const listener of listeners) listener(current);
}

/**
 * Call `listener` with the new session (or null) whenever it changes.
 * @param {SessionListener} listener
 * @returns {() => boolean} to stop listening
 */
export function onSessionChange(listener) {
  listeners.add(listener);
  return () => listeners.delete(listener);
}

/** @returns {MeOut | null} */
export function session() {
  return current;
}

/**
 * Whether the signed-in user may do `action` (the names of docs/permissions.md, e.g. "ride.delete").
 * Rules "own" need `ownerId`, the id of the user who made the thing. Pages hide the controls this
 * answers false for, so a member never sees a button that the API would answer with 403.
 * @param {string} action
 * @param {number | null} [ownerId]
 * @returns {boolean}
 */
export function can(action, ownerId = null) {
  const grant = current?.permissions?.[action];
  if (grant === "all") return true;
  if (grant === "own") return ownerId != null && ownerId === current?.user.id;
  return false;
}

/** True for a club admin. */
export function isAdmin() {
  return current?.user?.role === "admin";
}

function hasSessionCookies() {
  // The CSRF cookie is readable and set together with the (HttpOnly) session cookie.
  return document.cookie.split(";").some((part) => part.trim().startsWith("saddlescope_csrf="));
}

/**
 * Ask the server who we are; null when not signed in.
 * @returns {Promise<MeOut | null>}
 */
export async function refreshSession() {
  if (!hasSessionCookies()) {
    // Without the cookies the answer is a 401 for sure; skip the request (and its console error).
    current = null;
    changed();
    return current;
  }
  try {
    /** @type {MeOut | null} */
    const me = await get("/api/auth/me");
    current = me && me.user ? me : null;
  } catch (error) {
    if (!(error instanceof ApiError) || (error.status !== 401 && error.status !== 403)) throw error;
    current = null;
  }
  changed();
  return current;
}

/**
 * @param {string} email
 * @param {string} password
 * @returns {Promise<MeOut | null>}
 */
export async function signIn(email, password) {
  /** @type {import("./api-types").TokenOut | null} */
  const answer = await post("/api/auth/login", { email, password });
  setCsrfToken(answer?.csrf_token);
  await refreshSession();
  return current;
}

/**
 * Create a club and its first admin, and sign in as them.
 * @param {import("./api-types").ClubCreate} values
 */
export async function createClub(values) {
  await post("/api/clubs", values);
  return signIn(values.email, values.password);
}

export async function signOut() {
  try {
    await post("/api/auth/logout");
  } finally {
    setCsrfToken(null);
    current = null;
    changed();
  }
}

/**
 * Change the signed-in user's password. The server ends every session of the account (other browsers
 * and phones too); this browser signs straight back in with the new password so the user carries on.
 * Resolves to true when signed in again, false when the user must sign in by hand.
 * @param {string} currentPassword
 * @param {string} newPassword
 * @returns {Promise<boolean>}
 */
export async function changePassword(currentPassword, newPassword) {
  const email = current?.user?.email;
  await post("/api/auth/password", { current_password: currentPassword, new_password: newPassword });
  setCsrfToken(null);
  try {
    if (!email) throw new Error("nobody was signed in");
    await signIn(email, newPassword);
    return Boolean(current);
  } catch (error) {
    console.info("signing back in after the password change failed:", error instanceof Error ? error.message : error);
    current = null;
    changed();
    return false;
  }
}

/** End every session of the signed-in user (all browsers, phones and tokens), this one included. */
export async function signOutEverywhere() {
  await post("/api/auth/logout-everywhere");
  setCsrfToken(null);
  current = null;
  changed();
}

// A 401 anywhere means the session is gone: forget it so the pages send the user to sign in.
onUnauthorised(() => {
  if (current) {
    current = null;
    changed();
  }
});
