// Tables of rides: `rideTable(items, actions)` draws one (horse names link to the horse page;
// with `actions`, Edit and, where allowed, Delete per row), and [data-ride-table data-limit="N"] on a
// page (the overview) gets the club's N newest rides.

import { get, itemsOf } from "./api.js";
import { h, showError } from "./dom.js";
import { fmt, gaitLabel } from "./format.js";
import { can } from "./session.js";

/** @typedef {import("./api-types").RideOut} RideOut */
/**
 * What a row of the table offers besides "Open": Edit and, where allowed, Delete.
 * @typedef {object} RideActions
 * @property {(ride: RideOut) => unknown} [onEdit]
 * @property {(ride: RideOut) => unknown} [onDelete]
 */

/** @param {string} status */
function statusBadge(status) {
  return h("span", { class: `badge status-${status}` }, status);
}

/**
 * @param {RideOut} ride
 * @param {string} key
 */
function indicatorOf(ride, key) {
  return ride.indicators?.[key];
}

/**
 * A short name of a ride for headings and confirmations: "#12 Bravo, canter, 2026-03-01".
 * @param {RideOut} ride
 */
export function rideTitle(ride) {
  const date = ride.ridden_on ?? (ride.created_at ? ride.created_at.slice(0, 10) : "no date");
  return `#${ride.id} ${ride.horse_name}, ${gaitLabel(ride.gait)}, ${date}`;
}

/**
 * @param {RideOut} ride
 * @param {RideActions} actions
 */
function actionsCell(ride, actions) {
  const title = rideTitle(ride);
  const cell = h("td", { class: "actions" },
    h("a", { href: `#/rides/${ride.id}`, "aria-label": `Open ride ${title}` }, "Open"),
    actions.onEdit ? h("button", { type: "button", class: "link-button", "data-ride-edit": ride.id,
                                   "aria-label": `Edit ride ${title}`, onclick: () => actions.onEdit?.(ride) }, "Edit")
      : null);
  // Only the ride's maker and admins may delete it: nobody else sees the button (docs/permissions.md).
  if (actions.onDelete && can("ride.delete", ride.created_by)) {
    cell.append(h("button", { type: "button", class: "link-button danger", "data-permission": "ride.delete",
                              "data-ride-delete": ride.id, "aria-label": `Delete ride ${title}`,
                              onclick: () => actions.onDelete?.(ride) }, "Delete"));
  }
  return cell;
}

/**
 * @param {RideOut[]} items
 * @param {RideActions | null} [actions]
 */
export function rideTable(items, actions = null) {
  const body = items.map((ride) => h("tr", { dataset: { rideId: ride.id, ownerId: ride.created_by ?? "" } },
    h("td", {}, h("a", { href: `#/rides/${ride.id}` }, `#${ride.id}`)),
    h("td", {}, h("a", { href: `#/horses/${ride.horse_id}` }, ride.horse_name)),
    h("td", {}, ride.rider_name),
    h("td", {}, gaitLabel(ride.gait)),
    h("td", {}, ride.direction ?? ""),
    h("td", { class: "nowrap" }, ride.ridden_on ?? (ride.created_at ? ride.created_at.slice(0, 10) : "")),
    h("td", {}, statusBadge(ride.status),
      ride.result_outdated_by?.length ? h("span", { class: "badge outdated", title: "details changed since the analysis" },
        "re-analyse") : null),
    h("td", { class: "num" }, fmt(indicatorOf(ride, "acc_y_wb_rms"))),
    h("td", { class: "num" }, fmt(indicatorOf(ride, "vdv_y_wb"))),
    actions ? actionsCell(ride, actions) : null));
  return h("div", { class: "table-wrap", tabindex: "0", role: "region", "aria-label": "Rides table" },
    h("table", { class: "data", "data-rides-table": true },
      h("thead", {}, h("tr", {},
        h("th", { scope: "col" }, "Ride"), h("th", { scope: "col" }, "Horse"), h("th", { scope: "col" }, "Rider"),
        h("th", { scope: "col" }, "Gait"), h("th", { scope: "col" }, "Dir."), h("th", { scope: "col" }, "Date"),
        h("th", { scope: "col" }, "Status"),
        h("th", { scope: "col", class: "num" }, "W", h("sub", {}, "b"), " r.m.s. (m/s\u00b2)"),
        h("th", { scope: "col", class: "num" }, "VDV W", h("sub", {}, "b"), " (m/s\u00b9\u00b7\u2077\u2075)"),
        actions ? h("th", { scope: "col" }, h("span", { class: "sr-only" }, "Actions")) : null)),
      h("tbody", {}, body)));
}

/**
 * The club's newest rides (container's data-limit, 50 unless said) in `container`.
 * @param {HTMLElement} container
 */
export async function attachRideTable(container) {
  const limit = Number(container.dataset.limit || 50);
  container.replaceChildren(h("p", { class: "form-error", role: "alert", "data-form-error": true, hidden: true }));
  /** @type {import("./api-types").Page_RideOut_} */
  let rides;
  try {
    rides = await get("/api/rides", { params: { limit, sort: "-id" } });
  } catch (error) {
    showError(container, error);
    return;
  }
  const items = itemsOf(rides);
  if (!items.length) {
    container.append(h("p", { class: "empty" }, "No rides yet. ", h("a", { href: "#/upload" }, "Upload the first one"), "."));
    return;
  }
  container.append(rideTable(items));
}
