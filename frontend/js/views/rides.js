// All rides of the club.

import { page } from "../dom.js";
import { attachRideTable } from "../ride-table.js";

export async function mountRides(view) {
  view.append(page("rides"));
  await Promise.all([...view.querySelectorAll("[data-ride-table]")].map(attachRideTable));
}
