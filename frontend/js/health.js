// Service health: the footer badge on every page and the panel on the overview ([data-health-*] hooks).
// Everyone sees one line ("Service OK" / "Service degraded: <reason>") from the public /api/health;
// club admins also get each part's detail (versions, queue, storage folder) from /api/health/details.

import { get } from "./api.js";
import { h, maybeOne, messageOf, one } from "./dom.js";
import { isAdmin } from "./session.js";

/** @typedef {import("./api-types").HealthSummaryOut} HealthSummary */
/** @typedef {import("./api-types").HealthOut} HealthDetails */

/** @returns {Promise<HealthSummary>} */
async function fetchHealth() {
  // 503 still carries the report (a part is not ok), so read the body whatever the status.
  const response = await fetch("/api/health", { headers: { Accept: "application/json" } });
  return response.json();
}

/** @type {Record<string, string>} */
const PART_NAMES = { database: "Database", broker: "Job queue", storage: "File storage" };

/**
 * @param {string} name
 * @param {import("./api-types").PartHealth} part
 */
function row(name, part) {
  return h("tr", { dataset: { part: name } },
    h("th", { scope: "row" }, PART_NAMES[name] ?? name),
    h("td", { class: part.ok ? "ok" : "error" }, part.ok ? "ok" : "not ok"),
    h("td", {}, part.detail));
}

/** @param {ParentNode} root */
async function showDetails(root) {
  const box = maybeOne(root, "[data-health-details]");
  if (!box) return;
  if (!isAdmin()) {
    box.hidden = true;
    one(root, "[data-health-table]", HTMLTableElement).tBodies[0].replaceChildren();
    return;
  }
  /** @type {HealthDetails} */
  const details = await get("/api/health/details");
  one(root, "[data-health-version]").textContent =
    `SaddleScope ${details.version}, jobs run ${details.mode === "celery" ? "on Celery workers" : "on this server (embedded)"}.`;
  one(root, "[data-health-table]", HTMLTableElement).tBodies[0].replaceChildren(
    ...Object.entries(details.parts).map(([name, part]) => row(name, part)));
  box.hidden = false;
}

/**
 * Fill the health summary under `root` (the overview's panel) and the footer badge.
 * @param {ParentNode} [root]
 */
export async function checkHealth(root = document) {
  const summary = maybeOne(root, "[data-health-summary]");
  const badge = maybeOne(document, "[data-health-badge]");
  if (summary) summary.textContent = "Checking\u2026";
  try {
    const health = await fetchHealth();
    for (const el of [summary, badge]) {
      if (!el) continue;
      el.textContent = health.summary ?? (health.status === "ok" ? "Service OK" : "Service degraded");
      el.dataset.status = health.status;
    }
    if (summary) await showDetails(root);
  } catch (error) {
    for (const el of [summary, badge]) {
      if (!el) continue;
      el.textContent = `Cannot reach the server: ${messageOf(error)}`;
      el.dataset.status = "error";
    }
  }
}

/**
 * Attach the overview's health panel (refresh button).
 * @param {ParentNode} root
 */
export function attachHealthPanel(root) {
  const refresh = root.querySelector("[data-health-refresh]");
  if (refresh) refresh.addEventListener("click", () => checkHealth(root));
  return checkHealth(root);
}
