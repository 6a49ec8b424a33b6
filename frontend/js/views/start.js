// "Getting started": a new club's first page. It walks the club through its rig, the calibration board,
// filming (the guide of docs/filming.md, in short, with a drawing of the three cameras and the markers)
// and its first ride, ticking each step the club has done.

import { get } from "../api.js";
import { h, maybeOne, messageOf, page } from "../dom.js";

/**
 * Whether the list at `url` passes `test` (has a row, unless said): its first 50 rows.
 * @template T the list's rows
 * @param {string} url
 * @param {(items: T[]) => boolean} [test]
 */
async function has(url, test = (items) => items.length > 0) {
  try {
    /** @type {T[] | {items?: T[]} | null} a list, or a Page of one */
    const answer = await get(url, { params: { limit: 50 } });
    return test(Array.isArray(answer) ? answer : answer?.items ?? []);
  } catch (error) {
    console.info(`cannot read ${url}:`, messageOf(error));
    return false; // unknown: the step is simply not ticked
  }
}

/** @param {HTMLElement} view */
export async function mountStart(view) {
  view.append(page("start"));
  const [rig, calibrated, horse, ride] = await Promise.all([
    has("/api/rigs"),
    has("/api/rigs", (/** @type {import("../api-types").RigOut[]} */ rigs) => rigs.some((r) => r.calibrated)),
    has("/api/horses"),
    has("/api/rides"),
  ]);
  const done = { rig, board: calibrated, filming: ride, ride };
  for (const [step, isDone] of Object.entries(done)) {
    const item = maybeOne(view, `[data-start-step="${step}"]`);
    if (!item || !isDone) continue;
    item.classList.add("done");
    item.querySelector("h2")?.append(h("span", { class: "step-done" }, " \u2713 done"));
  }
  if (!horse) maybeOne(view, "[data-start-horse-hint]")?.removeAttribute("hidden");
}
