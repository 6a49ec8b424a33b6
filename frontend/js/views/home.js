// The overview: a new club's next steps, the latest rides and the service's health.

import { get } from "../api.js";
import { h, page } from "../dom.js";
import { attachHealthPanel } from "../health.js";
import { attachRideTable } from "../ride-table.js";

const STEPS = { rig: "/api/rigs", horse: "/api/horses", rider: "/api/riders", ride: "/api/rides" };

async function countOf(url) {
  try {
    const answer = await get(url, { params: { limit: 1 } });
    return Array.isArray(answer) ? answer.length : Number(answer?.total ?? 0);
  } catch (error) {
    console.info(`cannot count ${url}:`, error.message);
    return null; // unknown: that step is simply not marked done
  }
}

/** Show "Getting started" until the club has a rig, a horse, a rider and a ride; tick the steps done. */
async function showNextSteps(view) {
  const panel = view.querySelector("[data-getting-started]");
  const names = Object.keys(STEPS);
  const counts = Object.fromEntries(
    (await Promise.all(names.map((name) => countOf(STEPS[name])))).map((n, i) => [names[i], n]));
  const done = {
    rig: counts.rig > 0,
    horse: counts.horse > 0 && counts.rider > 0,
    ride: counts.ride > 0,
  };
  if (Object.values(done).every(Boolean)) return;
  for (const [step, isDone] of Object.entries(done)) {
    const item = panel.querySelector(`[data-step="${step}"]`);
    item.classList.toggle("done", isDone);
    if (isDone) item.append(h("span", { class: "step-done" }, "\u2713 done"));
  }
  panel.hidden = false;
}

export async function mountHome(view) {
  view.append(page("home"));
  await Promise.all([
    showNextSteps(view),
    attachHealthPanel(view),
    ...[...view.querySelectorAll("[data-ride-table]")].map(attachRideTable),
  ]);
}
