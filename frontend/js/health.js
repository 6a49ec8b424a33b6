// /api/health: the footer badge on every page and the table on the overview ([data-health-*] hooks).

import { h } from "./dom.js";

async function fetchHealth() {
  // 503 still carries the report (a part is not ok), so read the body whatever the status.
  const response = await fetch("/api/health", { headers: { Accept: "application/json" } });
  return response.json();
}

function row(name, part) {
  return h("tr", { dataset: { part: name } },
    h("td", {}, name),
    h("td", { class: part.ok ? "ok" : "error" }, part.ok ? "ok" : "error"),
    h("td", {}, part.detail));
}

export async function checkHealth(root = document) {
  const summary = root.querySelector("[data-health-summary]");
  const table = root.querySelector("[data-health-table]");
  const badge = document.querySelector("[data-health-badge]");
  if (summary) summary.textContent = "Checking\u2026";
  try {
    const health = await fetchHealth();
    const text = `SaddleScope ${health.version} (${health.mode} mode): ` +
      (health.status === "ok" ? "all parts ok" : "some parts are not ok");
    if (table) {
      table.tBodies[0].replaceChildren(...Object.entries(health.parts).map(([name, part]) => row(name, part)));
      table.hidden = false;
    }
    for (const el of [summary, badge]) {
      if (!el) continue;
      el.textContent = el === badge ? `Server ${health.status === "ok" ? "ok" : "has a problem"} \u00b7 v${health.version} \u00b7 ${health.mode}` : text;
      el.dataset.status = health.status;
    }
  } catch (error) {
    for (const el of [summary, badge]) {
      if (!el) continue;
      el.textContent = `Cannot reach the server: ${error.message}`;
      el.dataset.status = "error";
    }
  }
}

/** Attach the overview's health panel (refresh button). */
export function attachHealthPanel(root) {
  const refresh = root.querySelector("[data-health-refresh]");
  if (refresh) refresh.addEventListener("click", () => checkHealth(root));
  return checkHealth(root);
}
