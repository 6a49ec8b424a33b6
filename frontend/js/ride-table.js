// [data-ride-table data-limit="N"]: a table of the club's rides, newest first, with key indicators.

import { get, itemsOf } from "./api.js";
import { h, showError } from "./dom.js";
import { fmt, gaitLabel } from "./format.js";
import { horseName, nameLookups, riderName } from "./lookups.js";

function statusBadge(status) {
  return h("span", { class: `badge status-${status}` }, status);
}

function indicatorOf(ride, key) {
  return ride.indicators?.[key] ?? ride.result?.indicators?.[key] ?? ride[key];
}

export async function attachRideTable(container) {
  const limit = Number(container.dataset.limit || 50);
  container.replaceChildren(h("p", { class: "form-error", role: "alert", "data-form-error": true, hidden: true }));
  let rides;
  let lookups;
  try {
    [rides, lookups] = await Promise.all([get("/api/rides", { params: { limit } }), nameLookups()]);
  } catch (error) {
    showError(container, error);
    return;
  }
  const items = itemsOf(rides).sort((a, b) => b.id - a.id);
  if (!items.length) {
    container.append(h("p", { class: "empty" }, "No rides yet. ", h("a", { href: "#/upload" }, "Upload the first one"), "."));
    return;
  }
  const body = items.map((ride) => h("tr", { dataset: { rideId: ride.id } },
    h("td", {}, h("a", { href: `#/rides/${ride.id}` }, `#${ride.id}`)),
    h("td", {}, horseName(ride, lookups)),
    h("td", {}, riderName(ride, lookups)),
    h("td", {}, gaitLabel(ride.gait)),
    h("td", {}, ride.direction ?? ""),
    h("td", {}, ride.ridden_on ?? (ride.created_at ? ride.created_at.slice(0, 10) : "")),
    h("td", {}, statusBadge(ride.status)),
    h("td", { class: "num" }, fmt(indicatorOf(ride, "acc_y_wb_rms"))),
    h("td", { class: "num" }, fmt(indicatorOf(ride, "vdv_y_wb")))));
  container.append(h("div", { class: "table-wrap" }, h("table", { class: "data" },
    h("thead", {}, h("tr", {},
      h("th", { scope: "col" }, "Ride"), h("th", { scope: "col" }, "Horse"), h("th", { scope: "col" }, "Rider"),
      h("th", { scope: "col" }, "Gait"), h("th", { scope: "col" }, "Dir."), h("th", { scope: "col" }, "Date"),
      h("th", { scope: "col" }, "Status"),
      h("th", { scope: "col", class: "num" }, "W", h("sub", {}, "b"), " r.m.s. (m/s\u00b2)"),
      h("th", { scope: "col", class: "num" }, "VDV W", h("sub", {}, "b"), " (m/s\u00b9\u00b7\u2077\u2075)"))),
    h("tbody", {}, body))));
}
