// #/reset-password?token=...: a member sets a new password with the one-time link a club admin gave
// them (no sign-in needed: the token is the credential, and it works once).

import { post } from "../api.js";
import { announce, busy, field, one, page, showError } from "../dom.js";

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} _params
 * @param {URLSearchParams} query
 */
export function mountResetPassword(view, _params, query) {
  view.append(page("reset-password"));
  const form = one(view, "[data-reset-form]", HTMLFormElement);
  const token = query.get("token");
  if (!token) {
    form.hidden = true;
    one(view, "[data-reset-intro]").hidden = true;
    one(view, "[data-reset-missing]").hidden = false;
    return;
  }
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    const password = field(form, "new_password").value;
    const problem = password.length < 8 ? "The new password needs at least 8 characters."
      : password !== field(form, "repeat_password").value ? "The two passwords differ; type the same one twice."
        : null;
    showError(form, problem);
    if (problem) return;
    try {
      await busy(form, () => post("/api/auth/password-reset", { token, new_password: password }));
    } catch (error) {
      showError(form, error);
      return;
    }
    // The link is spent: take it out of the address bar and the history.
    window.history.replaceState(null, "", `${window.location.pathname}#/reset-password`);
    form.hidden = true;
    one(view, "[data-reset-intro]").hidden = true;
    one(view, "[data-reset-done]").hidden = false;
    announce("Your password is set. Sign in with it.");
  });
}
