// Sign in, or create a club (which signs its first administrator in).

import { announce, busy, formValues, page, showError } from "../dom.js";
import { plainReason } from "../form-errors.js";
import { navigate } from "../router.js";
import { createClub, signIn } from "../session.js";

function nextPath(query) {
  const next = query.get("next");
  // Only our own hash routes, never an outside address.
  return next && next.startsWith("/") && !next.startsWith("//") ? next : "/";
}

function requireFields(form) {
  for (const el of form.querySelectorAll("[required]")) {
    if (!el.value.trim()) {
      const label = form.querySelector(`label[for="${el.id}"]`)?.textContent ?? el.name;
      el.focus();
      return `Please fill in: ${label}.`;
    }
  }
  return null;
}

export function mountLogin(view, _params, query) {
  view.append(page("login"));
  const loginForm = view.querySelector("[data-login-form]");
  const registerForm = view.querySelector("[data-register-form]");

  loginForm.addEventListener("submit", async (event) => {
    event.preventDefault();
    const missing = requireFields(loginForm);
    showError(loginForm, missing);
    if (missing) return;
    const { email, password } = formValues(loginForm);
    try {
      await busy(loginForm, () => signIn(email, password));
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
      await busy(registerForm, () => createClub(formValues(registerForm)));
    } catch (error) {
      showError(registerForm, plainReason(error));
      return;
    }
    announce("Club created; you are signed in.");
    navigate("/start");
  });
}
