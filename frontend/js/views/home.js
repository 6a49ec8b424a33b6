// The overview: latest rides and the service's health.

import { page } from "../dom.js";
import { attachHealthPanel } from "../health.js";
import { attachRideTable } from "../ride-table.js";

export async function mountHome(view) {
  view.append(page("home"));
  await Promise.all([
    attachHealthPanel(view),
    ...[...view.querySelectorAll("[data-ride-table]")].map(attachRideTable),
  ]);
}
