// Your account: change the password, sign out everywhere; club admins also manage the members
// (add, role, disable/enable, a one-time password-reset link to hand over: no mail server needed).

import { get, patch, post } from "../api.js";
import { announce, busy, copyText, field, formValues, h, messageOf, one, page, showError } from "../dom.js";
import { navigate } from "../router.js";
import { can, changePassword, refreshSession, session, signOutEverywhere } from "../session.js";
import { mountShareLinks } from "../share.js";

/** @typedef {import("../api-types").UserOut} UserOut */

const MEMBERS_PER_PAGE = 20;
const MANAGE = "user.manage";

/**
 * @param {string | number | undefined} password
 * @param {string | number | undefined} repeat
 */
function passwordProblem(password, repeat) {
  if (!password || String(password).length < 8) return "The new password needs at least 8 characters.";
  if (password !== repeat) return "The two new passwords differ; type the same one twice.";
  return null;
}

/** @param {HTMLElement} view */
function attachPasswordForm(view) {
  const form = one(view, "[data-password-form]", HTMLFormElement);
  const ok = one(form, "[data-form-ok]");
  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    ok.hidden = true;
    const values = formValues(form);
    const problem = !values.current_password ? "Type your current password."
      : passwordProblem(field(form, "new_password").value, field(form, "repeat_password").value);
    showError(form, problem);
    if (problem) return;
    let stillSignedIn;
    try {
      stillSignedIn = await busy(form, () => changePassword(field(form, "current_password").value,
        field(form, "new_password").value));
    } catch (error) {
      showError(form, error);
      return;
    }
    form.reset();
    if (!stillSignedIn) {
      navigate("/login");
      return;
    }
    ok.textContent = "Password changed. Your other browsers and phones are signed out.";
    ok.hidden = false;
    announce(ok.textContent);
  });
}

/** @param {HTMLElement} view */
function attachSignOutEverywhere(view) {
  const box = one(view, "[data-everywhere]");
  one(box, "[data-sign-out-everywhere]").addEventListener("click", async () => {
    if (!window.confirm("Sign out on every browser and phone, this one too?")) return;
    try {
      await signOutEverywhere();
    } catch (error) {
      showError(box, error);
      return;
    }
    announce("Signed out everywhere.");
    navigate("/login");
  });
}

/**
 * "<origin>/#/reset-password?token=..." : what the admin hands to the member.
 * @param {string} token
 */
function resetLink(token) {
  const base = `${window.location.origin}${window.location.pathname}`;
  return `${base}#/reset-password?token=${encodeURIComponent(token)}`;
}

class Members {
  /** @param {HTMLElement} view */
  constructor(view) {
    this.section = one(view, "[data-members]");
    this.table = one(this.section, "[data-members-table]", HTMLTableElement);
    this.error = one(this.section, "[data-members-error]");
    this.pager = one(this.section, "[data-members-pager]");
    this.resetBox = one(this.section, "[data-reset-box]");
    this.offset = 0;
    this.total = 0;
    this.me = session()?.user?.id;
    /** @type {Promise<void> | undefined} the change under way; the next waits for it */
    this.changing = undefined;
  }

  attach() {
    this.section.hidden = false;
    one(this.pager, '[data-page="prev"]').addEventListener("click", () => this.turn(-1));
    one(this.pager, '[data-page="next"]').addEventListener("click", () => this.turn(1));
    const copy = one(this.resetBox, "[data-reset-copy]");
    copy.addEventListener("click", async () => {
      const copied = await copyText(one(this.resetBox, "[data-reset-link]", HTMLInputElement));
      copy.textContent = copied ? "Copied" : "Select and copy it";
      announce(copied ? "Link copied." : "Select the link and copy it.");
    });
    this.attachAddForm();
    return this.load();
  }

  /** @param {unknown} error a sentence, an Error, or null to hide it */
  showError(error) {
    this.error.textContent = error ? (typeof error === "string" ? error : messageOf(error)) : "";
    this.error.hidden = !error;
  }

  /** @param {number} step -1: the page before, 1: the page after */
  turn(step) {
    this.offset = Math.max(0, this.offset + step * MEMBERS_PER_PAGE);
    return this.load();
  }

  async load() {
    /** @type {import("../api-types").Page_UserOut_} */
    let answer;
    try {
      answer = await get("/api/users", { params: { limit: MEMBERS_PER_PAGE, offset: this.offset, sort: "email" } });
    } catch (error) {
      this.showError(error);
      return;
    }
    this.total = answer.total;
    if (!answer.items.length && this.offset > 0) {
      this.offset = 0;
      await this.load();
      return;
    }
    this.table.tBodies[0].replaceChildren(...answer.items.map((user) => this.row(user)));
    const last = Math.min(this.offset + answer.items.length, this.total);
    one(this.pager, "[data-page-info]").textContent = `${this.offset + 1}\u2013${last} of ${this.total}`;
    one(this.pager, '[data-page="prev"]', HTMLButtonElement).disabled = this.offset === 0;
    one(this.pager, '[data-page="next"]', HTMLButtonElement).disabled = last >= this.total;
    this.pager.hidden = this.total <= MEMBERS_PER_PAGE;
  }

  /** @param {UserOut} user */
  row(user) {
    const name = user.display_name || user.email;
    const isMe = user.id === this.me;
    const role = h("select", { "aria-label": `Role of ${name}`, "data-permission": MANAGE, dataset: { role: user.id } },
      h("option", { value: "member", selected: user.role === "member" }, "Member"),
      h("option", { value: "admin", selected: user.role === "admin" }, "Admin"));
    // its options are the two roles
    role.addEventListener("change", () => this.change(user, { role: /** @type {UserOut["role"]} */ (role.value) }, role));
    // Never yourself: an admin who disabled their own account would be signed out on the spot.
    const toggle = isMe ? null : h("button", {
      type: "button", class: `link-button${user.is_active ? " danger" : ""}`, "data-permission": MANAGE,
      onclick: () => this.change(user, { is_active: !user.is_active }),
    }, user.is_active ? "Disable" : "Enable");
    // Not for yourself (change it above) nor a disabled account (a reset link only works when active).
    const reset = isMe || !user.is_active ? null : h("button", {
      type: "button", class: "link-button", "data-permission": MANAGE, onclick: () => this.issueReset(user),
    }, "Reset link");
    return h("tr", { dataset: { userId: user.id, email: user.email } },
      h("th", { scope: "row" }, user.display_name || "\u2014", isMe ? h("span", { class: "hint" }, " (you)") : null),
      h("td", { class: "email" }, user.email),
      h("td", {}, role),
      h("td", {}, h("span", { class: `badge ${user.is_active ? "status-done" : "status-failed"}` },
        user.is_active ? "active" : "disabled")),
      h("td", { class: "actions" }, toggle, reset));
  }

  /**
   * @param {UserOut} user
   * @param {import("../api-types").UserUpdate} changes
   * @param {HTMLSelectElement | null} [control] the role's select, set back when refused
   */
  change(user, changes, control = null) {
    // One change at a time: the next waits until the table shows the last one (had the admin dropped
    // their own rights meanwhile, that reload would be refused).
    this.changing = (this.changing ?? Promise.resolve())
      .then(() => this.applyChange(user, changes, control))
      .catch((error) => this.showError(error));
    return this.changing;
  }

  /**
   * @param {UserOut} user
   * @param {import("../api-types").UserUpdate} changes
   * @param {HTMLSelectElement | null} [control]
   */
  async applyChange(user, changes, control = null) {
    const name = user.display_name || user.email;
    const losingOwnRights = user.id === this.me && (changes.role === "member" || changes.is_active === false);
    if (losingOwnRights && !window.confirm("You will no longer be an admin of the club. Go on?")) {
      if (control) control.value = user.role;
      return;
    }
    if (changes.is_active === false && user.id !== this.me
        && !window.confirm(`Disable ${name}? They are signed out at once and cannot sign in until enabled.`)) return;
    this.showError(null);
    try {
      await patch(`/api/users/${user.id}`, changes);
    } catch (error) {
      if (control) control.value = user.role; // refused (e.g. the last admin): show what is stored
      this.showError(error);
      return;
    }
    if (losingOwnRights) {
      announce(`${name} changed.`);
      await refreshSession(); // the role (and its permissions) as the server now sees us
      navigate("/account"); // the page without the members section
      return;
    }
    // Announce once the table shows the change: a next change must not race this reload (which, after
    // the admin stepped down meanwhile, would be refused).
    await this.load();
    announce(`${name} changed.`);
  }

  /**
   * @param {UserOut} user
   * @param {{fresh?: boolean}} [options] fresh: the member was just added (no question asked)
   */
  async issueReset(user, { fresh = false } = {}) {
    const name = user.display_name || user.email;
    if (!fresh && !window.confirm(`Make a one-time link for ${name}? Their current password stops working now.`)) return;
    this.showError(null);
    /** @type {import("../api-types").PasswordResetOut} */
    let answer;
    try {
      answer = await post(`/api/users/${user.id}/password-reset`);
    } catch (error) {
      this.showError(error);
      return;
    }
    const link = one(this.resetBox, "[data-reset-link]", HTMLInputElement);
    link.value = resetLink(answer.reset_token);
    one(this.resetBox, "[data-reset-for]").textContent = fresh
      ? `${name} was added. Give them this link to set their password (it is shown only now):`
      : `One-time link for ${name} (shown only now; give it to them):`;
    one(this.resetBox, "[data-reset-expiry]").textContent =
      `It works once, until ${new Date(answer.expires_at).toLocaleString()}.`;
    one(this.resetBox, "[data-reset-copy]").textContent = "Copy link";
    this.resetBox.hidden = false;
    link.focus();
    link.select();
  }

  attachAddForm() {
    const form = one(this.section, "[data-add-member]", HTMLFormElement);
    const passwordField = one(form, "[data-initial-password]");
    const firstSignIn = field(form, "first_sign_in", RadioNodeList);
    for (const radio of firstSignIn) {
      radio.addEventListener("change", () => { passwordField.hidden = firstSignIn.value !== "password"; });
    }
    form.addEventListener("submit", (event) => {
      event.preventDefault();
      this.add(form, passwordField);
    });
  }

  /**
   * @param {HTMLFormElement} form
   * @param {HTMLElement} passwordField
   */
  async add(form, passwordField) {
    const values = formValues(form);
    const byLink = values.first_sign_in === "link";
    let problem = values.email ? null : "Type the member's e-mail address.";
    if (!problem && !byLink) problem = passwordProblem(values.password, values.password);
    showError(form, problem);
    if (problem) return;
    // With a link, the account gets a random password nobody knows; the reset link replaces it.
    const password = byLink ? randomPassword() : values.password;
    /** @type {UserOut} */
    let user;
    try {
      user = await busy(form, () => post("/api/users", {
        email: values.email, display_name: values.display_name ?? "", role: values.role, password,
      }));
    } catch (error) {
      showError(form, error);
      return;
    }
    form.reset();
    passwordField.hidden = true;
    announce(`${user.email} added.`);
    if (byLink) await this.issueReset(user, { fresh: true });
    await this.load();
  }
}

function randomPassword() {
  const bytes = crypto.getRandomValues(new Uint8Array(24));
  return Array.from(bytes, (b) => b.toString(16).padStart(2, "0")).join("");
}

/** @param {HTMLElement} view */
export async function mountAccount(view) {
  view.append(page("account"));
  const me = session();
  one(view, "[data-account-who]").textContent = me
    ? `${me.user.display_name ? `${me.user.display_name}, ` : ""}${me.user.email} \u00b7 ${me.user.role === "admin" ? "admin" : "member"} of ${me.club?.name ?? "your club"}`
    : "";
  attachPasswordForm(view);
  attachSignOutEverywhere(view);
  if (can(MANAGE)) await new Members(view).attach();
  else one(view, "[data-members]").remove(); // members never get the admins' controls at all
  if (can("share.manage")) await mountShareLinks(one(view, "[data-share-links]"));
  else one(view, "[data-share-links]").remove();
}
