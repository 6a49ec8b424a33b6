// The overview: a new club's next steps, the latest rides and the service's health.

import { get } from "../api.js";
import { all, h, messageOf, one, page } from "../dom.js";
import { attachHealthPanel } from "../health.js";
import { attachRideTable } from "../ride-table.js";

/** @type {Record<string, string>} */
const STEPS = { rig: "/api/rigs", horse: "/api/horses", rider: "/api/riders", ride: "/api/rides" };

/**
 * How many rows a list has (a Page's total); null when it cannot be read.
 * @param {string} url
 * @returns {Promise<number | null>}
 */
async function countOf(url) {
  try {
    /** @type {{total?: number} | unknown[] | null} */
    const answer = await get(url, { params: { limit: 1 } });
    return Array.isArray(answer) ? answer.length : Number(answer?.total ?? 0);
  } catch (error) {
    console.info(`cannot count ${url}:`, messageOf(error));
    return null; // unknown: that step is simply not marked done
  }
}

/**
 * Show "Getting started" until the club has a rig, a horse, a rider and a ride; tick the steps done.
 * @param {HTMLElement} view
 */
async function showNextSteps(view) {
  const panel = one(view, "[data-getting-started]");
  const names = Object.keys(STEPS);
  const counts = Object.fromEntries(
    (await Promise.all(names.map((name) => countOf(STEPS[name])))).map((n, i) => [names[i], n]));
  const more = (/** @type {number | null} */ n) => n !== null && n > 0; // null: unknown, not done
  const done = {
    rig: more(counts.rig),
    horse: more(counts.horse) && more(counts.rider),
    ride: more(counts.ride),
  };
  if (Object.values(done).every(Boolean)) return;
  for (const [step, isDone] of Object.entries(done)) {
    const item = one(panel, `[data-step="${step}"]`);
    item.classList.toggle("done", isDone);
    if (isDone) item.append(h("span", { class: "step-done" }, "\u2713 done"));
  }
  panel.hidden = false;
}

/** @param {HTMLElement} view */
export async function mountHome(view) {
  view.append(page("home"));
  await Promise.all([
    showNextSteps(view),
    attachHealthPanel(view),
    ...all(view, "[data-ride-table]").map(attachRideTable),
  ]);
}
