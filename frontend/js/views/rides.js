// All rides of the club: filtered, sorted and paged by the server, the state in the URL
// (#/rides?horse_id=3&gait=canter&page=2&sort=-ridden_on); "Edit" opens the ride's details above
// the list (&edit=12), Delete (its maker and admins only) asks first.

import { get, itemsOf } from "../api.js";
import { h, messageOf, one, page, showError } from "../dom.js";
import { poll } from "../poll.js";
import { fillOptions } from "../options.js";
import { apiParams, bindFilterForm, listState, pager, updateQuery } from "../pager.js";
import { deleteRideWithConfirmation, mountRideEdit } from "../ride-edit.js";
import { rideTable, rideTitle } from "../ride-table.js";

const FILTERS = ["horse_id", "rider_id", "gait", "status", "date_from", "date_to"];
// A ride in these states is waiting for or inside its analysis: its badge is followed live.
const UNDER_WAY = new Set(["ready", "processing"]);

/** @typedef {import("../api-types").RideOut} RideOut */
/** @typedef {import("../api-types").Page_RideOut_} RidePage */

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} params
 * @param {URLSearchParams} query
 */
export async function mountRides(view, params, query) {
  view.append(page("rides"));
  const state = listState(query, { filters: FILTERS, sort: "-ridden_on" });
  const form = one(view, "[data-rides-filter]", HTMLFormElement);
  const list = one(view, "[data-rides-list]");
  const pagerSlot = one(view, "[data-rides-pager]");
  const editSlot = one(view, "[data-ride-edit-slot]");
  const panel = /** @type {HTMLElement} */ (list.closest(".panel"));
  /** @type {RideOut[]} */
  let shown = [];

  /** @param {RideOut} ride */
  async function openEditor(ride) {
    editSlot.hidden = false;
    await mountRideEdit(editSlot, ride, {
      onSaved: () => load(),
      onDeleted: () => updateQuery({ edit: null }),
    });
    editSlot.prepend(h("button", { type: "button", class: "link-button close", "data-ride-edit-close": true,
                                   onclick: () => updateQuery({ edit: null }) }, "Close"));
    editSlot.scrollIntoView({ block: "start" });
  }

  /** @param {RideOut} ride */
  async function remove(ride) {
    try {
      if (await deleteRideWithConfirmation(ride, rideTitle(ride).replace(/^#/, "ride #"))) await load();
    } catch (error) {
      showError(panel, error);
    }
  }

  async function load() {
    /** @type {RidePage} */
    let answer;
    try {
      answer = await get("/api/rides", { params: apiParams(state) });
      showError(panel, null);
    } catch (error) {
      showError(panel, error);
      return;
    }
    const items = answer.items;
    shown = items;
    const filtered = FILTERS.some((name) => state.filters[name] !== "");
    list.replaceChildren(items.length ? rideTable(items, {
      onEdit: (ride) => updateQuery({ edit: ride.id }),
      onDelete: remove,
    }) : h("p", { class: "empty" }, filtered ? "No ride matches these filters. " : "No rides yet. ",
      filtered ? h("button", { type: "button", class: "link-button", onclick: () => one(form, "[data-filter-clear]").click() },
        "Clear the filters") : h("a", { href: "#/upload" }, "Upload the first one"), "."));
    pagerSlot.replaceChildren(pager(answer, state, { noun: "rides" }));
  }

  try {
    await fillOptions(form);
  } catch (error) {
    showError(panel, error);
  }
  bindFilterForm(form, state);
  await load();
  const editId = Number.parseInt(query.get("edit") ?? "", 10);
  if (editId > 0) {
    try {
      await openEditor(await get(`/api/rides/${editId}`));
    } catch (error) {
      showError(panel, error);
    }
  }
  // Status badges follow the rides' analyses without a reload: the list is drawn again when one changes
  // (looked at every 3 s while a ride is under way, else every 15 s: a ride may be started elsewhere).
  let first = true;
  const poller = poll(async () => {
    if (first) { first = false; return 3000; } // just drawn
    try {
      /** @type {RideOut[]} */
      const now = itemsOf(await get("/api/rides", { params: apiParams(state) }));
      const before = new Map(shown.map((ride) => [ride.id, ride.status]));
      if (now.some((ride) => before.get(ride.id) !== ride.status) && !editSlot.contains(document.activeElement)) await load();
    } catch (error) {
      console.info("rides not refreshed:", messageOf(error));
    }
    return shown.some((ride) => UNDER_WAY.has(ride.status)) ? 3000 : 15000;
  });
  return () => poller.stop();
}
