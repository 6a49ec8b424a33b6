// Sign in, or create a club (which signs its first administrator in).

import { all, announce, busy, formValues, one, page, showError } from "../dom.js";
import { plainReason } from "../form-errors.js";
import { navigate } from "../router.js";
import { createClub, signIn } from "../session.js";

/** @param {URLSearchParams} query */
function nextPath(query) {
  const next = query.get("next");
  // Only our own hash routes, never an outside address.
  return next && next.startsWith("/") && !next.startsWith("//") ? next : "/";
}

/**
 * The first empty required field, focused and named in a sentence; null when all are filled in.
 * @param {HTMLFormElement} form
 */
function requireFields(form) {
  for (const el of all(form, "[required]", HTMLInputElement)) {
    if (!el.value.trim()) {
      const label = form.querySelector(`label[for="${el.id}"]`)?.textContent ?? el.name;
      el.focus();
      return `Please fill in: ${label}.`;
    }
  }
  return null;
}

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} _params
 * @param {URLSearchParams} query
 */
export function mountLogin(view, _params, query) {
  view.append(page("login"));
  const loginForm = one(view, "[data-login-form]", HTMLFormElement);
  const registerForm = one(view, "[data-register-form]", HTMLFormElement);

  loginForm.addEventListener("submit", async (event) => {
    event.preventDefault();
    const missing = requireFields(loginForm);
    showError(loginForm, missing);
    if (missing) return;
    const { email, password } = formValues(loginForm);
    try {
      await busy(loginForm, () => signIn(String(email), String(password)));
    } catch (error) {
      showError(loginForm, plainReason(error));
      return;
    }
    announce("Signed in.");
    navigate(nextPath(query));
  });

  registerForm.addEventListener("submit", async (event) => {
    event.preventDefault();
    const missing = requireFields(registerForm);
    showError(registerForm, missing);
    if (missing) return;
    try {
      // the form's fields are ClubCreate's (club_name, email, password, display_name), all text
      await busy(registerForm, () => createClub(/** @type {import("../api-types").ClubCreate} */ (
        /** @type {unknown} */ (formValues(registerForm)))));
    } catch (error) {
      showError(registerForm, plainReason(error));
      return;
    }
    announce("Club created; you are signed in.");
    navigate("/start");
  });
}
