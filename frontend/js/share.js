// "Share with your vet": a read-only link to one ride's report or one horse's page for someone without an
// account (POST /api/share-links), shown once with a copy button; and the admins' list of the club's links
// with a button to withdraw one (docs/permissions.md, "Share links").

import { get, itemsOf, post } from "./api.js";
import { announce, copyText, formatDate, h, one, showError } from "./dom.js";
import { can } from "./session.js";

/** @typedef {import("./api-types").ShareLinkOut} ShareLink */

/** @type {[number, string][]} days, in words */
const LIFETIMES = [[7, "a week"], [30, "30 days"], [90, "3 months"], [365, "a year"]];
/** @type {Record<ShareLink["state"], string>} */
const STATE_WORDS = { active: "active", expired: "expired", withdrawn: "withdrawn" };
let serial = 0;

/** @param {string | null | undefined} value */
function day(value) {
  return value ? formatDate(value).slice(0, 10) : "";
}

/**
 * The made link, its copy button and what it lets the reader see.
 * @param {import("./api-types").ShareLinkCreated} made
 * @param {string} what
 */
function madeLink(made, what) {
  const id = `share-link-${++serial}`;
  const input = h("input", { id, readonly: true, value: `${window.location.origin}${made.path}`, dataset: { shareUrl: "" } });
  const copy = h("button", { type: "button", dataset: { shareCopy: "" }, onclick: async () => {
    const copied = await copyText(input);
    copy.textContent = copied ? "Copied" : "Select and copy it";
    announce(copied ? "Link copied." : "Select the link and copy it.");
  } }, "Copy link");
  return h("div", { class: "reset-link", role: "status" },
    h("p", {}, `Anyone with this link can read ${what}, without an account, until ${day(made.expires_at)}. `
      + "It is shown only now: copy it for your vet. A club admin can withdraw it on the Account page."),
    h("div", { class: "reset-link-row" }, h("label", { class: "sr-only", for: id }, "Share link"), input, copy));
}

/**
 * A "Share with your vet" control for a ride (`rideId`) or a horse (`horseId`); nothing for those who may not.
 * @param {{rideId?: number | null, horseId?: number | null}} target
 * @returns {HTMLDetailsElement | null}
 */
export function shareControl({ rideId = null, horseId = null }) {
  if (!can("share.create")) return null;
  const what = rideId ? "this ride's report" : "this horse's page and its rides' reports";
  const id = `share-days-${++serial}`;
  const result = h("div", { dataset: { shareResult: "" } });
  const error = h("p", { class: "form-error", role: "alert", dataset: { formError: "" }, hidden: true });
  const select = h("select", { id, name: "days" },
    ...LIFETIMES.map(([days, words]) => h("option", { value: String(days), selected: days === 30 }, words)));
  const form = h("form", { class: "share-form", novalidate: true, onsubmit: async (event) => {
    event.preventDefault();
    error.hidden = true;
    try {
      /** @type {import("./api-types").ShareLinkIn} */
      const asked = { ride_id: rideId, horse_id: horseId, days: Number(select.value) };
      /** @type {import("./api-types").ShareLinkCreated} */
      const made = await post("/api/share-links", asked);
      result.replaceChildren(madeLink(made, what));
      announce("Share link made.");
    } catch (failure) {
      showError(form, failure);
    }
  } },
  h("p", { class: "hint" }, `A read-only link to ${what} for someone without an account (a vet, a saddle fitter).`),
  h("div", { class: "share-row" },
    h("label", { for: id }, "Valid for"), select,
    h("button", { type: "submit", class: "primary", dataset: { shareMake: "" } }, "Make a link")),
  error);
  return h("details", { class: "share", dataset: { share: rideId ? "ride" : "horse" } },
    h("summary", {}, "Share with your vet"), form, result);
}

/**
 * @param {ShareLink} link
 * @param {() => Promise<void>} reload
 * @param {HTMLElement} box where a refusal is shown
 */
function linkRow(link, reload, box) {
  const withdraw = link.state === "active"
    ? h("button", { type: "button", dataset: { revoke: String(link.id) }, onclick: async () => {
      try {
        await post(`/api/share-links/${link.id}/revoke`);
        announce("Link withdrawn.");
        await reload();
      } catch (failure) {
        showError(box, failure);
      }
    } }, "Withdraw")
    : null;
  return h("tr", { dataset: { link: String(link.id) } },
    h("td", {}, link.shows), h("td", {}, link.created_by), h("td", {}, day(link.created_at)),
    h("td", {}, day(link.expires_at)), h("td", {}, STATE_WORDS[link.state] ?? "–"), h("td", {}, withdraw));
}

/**
 * The admins' list of the club's share links in `section` (a panel of the Account page).
 * @param {HTMLElement} section
 */
export async function mountShareLinks(section) {
  const body = one(section, "tbody", HTMLTableSectionElement);
  const empty = one(section, "[data-share-links-empty]");
  const reload = async () => {
    try {
      /** @type {ShareLink[]} */
      const links = itemsOf(await get("/api/share-links"));
      body.replaceChildren(...links.map((link) => linkRow(link, reload, section)));
      empty.hidden = links.length > 0;
    } catch (failure) {
      showError(section, failure);
    }
  };
  section.hidden = false;
  await reload();
}
