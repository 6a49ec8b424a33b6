// "Getting started": a new club's first page. It walks the club through its rig, the calibration board,
// filming (the guide of docs/filming.md, in short, with a drawing of the three cameras and the markers)
// and its first ride, ticking each step the club has done.

import { get } from "../api.js";
import { h, page } from "../dom.js";

async function has(url, test = (items) => items.length > 0) {
  try {
    const answer = await get(url, { params: { limit: 50 } });
    return test(Array.isArray(answer) ? answer : answer?.items ?? []);
  } catch (error) {
    console.info(`cannot read ${url}:`, error.message);
    return false; // unknown: the step is simply not ticked
  }
}

export async function mountStart(view) {
  view.append(page("start"));
  const [rig, calibrated, horse, ride] = await Promise.all([
    has("/api/rigs"),
    has("/api/rigs", (rigs) => rigs.some((r) => r.calibrated)),
    has("/api/horses"),
    has("/api/rides"),
  ]);
  const done = { rig, board: calibrated, filming: ride, ride };
  for (const [step, isDone] of Object.entries(done)) {
    const item = view.querySelector(`[data-start-step="${step}"]`);
    if (!item || !isDone) continue;
    item.classList.add("done");
    item.querySelector("h2")?.append(h("span", { class: "step-done" }, " \u2713 done"));
  }
  if (!horse) view.querySelector("[data-start-horse-hint]")?.removeAttribute("hidden");
}
