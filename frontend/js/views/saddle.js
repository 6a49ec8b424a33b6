// One saddle across the club's horses (#/saddles/:id): its details, per horse and gait the rides in it
// with each indicator's mean and 95 % interval, and its analysed rides, newest first. Rides too
// uncertain for a decision are listed (marked) but counted only when asked.

import { get } from "../api.js";
import { all, h, one, page, showError } from "../dom.js";
import { fmt, gaitLabel, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { meanIntervalText, saddleTypeText } from "../saddle-words.js";
import { onFormChange } from "./analysis-common.js";

/** @typedef {import("../api-types").SaddleOut} SaddleOut */
/** @typedef {import("../api-types").SaddleAcrossHorsesOut} AcrossHorses */

/**
 * @param {HTMLElement} view
 * @param {SaddleOut} saddle
 */
function showDetails(view, saddle) {
  one(view, "[data-saddle-name]").textContent = saddle.name;
  document.title = `${saddle.name} \u2013 SaddleScope`;
  /**
   * @param {string} term
   * @param {string} value
   * @param {string} key
   */
  const item = (term, value, key) => h("div", {}, h("dt", {}, term), h("dd", { dataset: { profile: key } }, value));
  one(view, "[data-saddle-profile]").replaceChildren(
    item("Maker", saddle.maker || "\u2013", "maker"),
    item("Type", saddleTypeText(saddle.saddle_type), "type"),
    item("Tree width", saddle.tree_width || "\u2013", "tree_width"),
    item("Rides", String(saddle.rides), "rides"),
    ...(saddle.notes ? [item("Notes", saddle.notes, "notes")] : []));
}

/**
 * @param {AcrossHorses} answer
 * @param {string[]} first the columns before the indicators'
 */
function headCells(answer, first) {
  return [...first.map((text) => h("th", { scope: "col" }, text)),
    ...Object.keys(answer.labels).map((key) => h("th", { scope: "col", class: "num" },
      `${labelText(answer.labels[key])} (${prettyUnit(answer.units[key])})`))];
}

/**
 * @param {HTMLElement} view
 * @param {AcrossHorses} answer
 */
function showHorses(view, answer) {
  const table = one(view, "[data-saddle-horses]", HTMLTableElement);
  const keys = Object.keys(answer.labels);
  /** @type {HTMLTableSectionElement} */ (table.tHead).rows[0].replaceChildren(...headCells(answer, ["Horse", "Gait", "Rides"]));
  table.tBodies[0].replaceChildren(...answer.horses.map((row) => h("tr", { dataset: { horseId: row.horse_id } },
    h("th", { scope: "row" }, h("a", { href: `#/horses/${row.horse_id}` }, row.horse)),
    h("td", {}, gaitLabel(row.gait)),
    h("td", { class: "num" }, String(row.rides)),
    ...keys.map((key) => h("td", { class: "num" }, meanIntervalText(row.indicators[key]))))));
  table.hidden = !answer.horses.length;
  one(view, "[data-saddle-horses-empty]").hidden = answer.horses.length > 0;
  one(view, "[data-saddle-method]").textContent =
    `Each value: the mean of the rides with its 95 % interval in brackets. ${answer.method}`;
}

/**
 * @param {HTMLElement} view
 * @param {AcrossHorses} answer
 */
function showRides(view, answer) {
  const table = one(view, "[data-saddle-rides]", HTMLTableElement);
  const keys = Object.keys(answer.labels);
  /** @type {HTMLTableSectionElement} */ (table.tHead).rows[0].replaceChildren(...headCells(answer, ["Date", "Horse", "Rider", "Gait"]));
  table.tBodies[0].replaceChildren(...answer.rides.map((ride) => h("tr", { dataset: { rideId: ride.ride_id } },
    h("th", { scope: "row" }, h("a", { href: `#/rides/${ride.ride_id}` }, ride.date ?? `ride #${ride.ride_id}`),
      ride.uncertain_reason ? h("span", { class: "badge", title: ride.uncertain_reason }, " too uncertain") : null),
    h("td", {}, ride.horse), h("td", {}, ride.rider), h("td", {}, gaitLabel(ride.gait)),
    ...keys.map((key) => h("td", { class: "num" }, fmt(ride.indicators[key]))))));
}

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} params
 */
export async function mountSaddle(view, params) {
  view.append(page("saddle"));
  /** @type {SaddleOut} */
  let saddle;
  try {
    saddle = await get(`/api/saddles/${params.id}`);
  } catch (error) {
    one(view, "[data-saddle-name]").textContent = "Saddle not found";
    showError(one(view, "[data-saddle-page-error]"), error);
    for (const panel of all(view, "section.panel")) panel.hidden = true;
    return;
  }
  showDetails(view, saddle);
  const form = one(view, "[data-saddle-form]", HTMLFormElement);
  await fillOptions(form);
  const section = /** @type {HTMLElement} */ (form.closest("section"));
  await onFormChange(form, async ({ gait, include_uncertain: includeUncertain }, current) => {
    try {
      /** @type {Record<string, string>} */
      const query = {};
      if (gait) query.gait = gait;
      if (includeUncertain) query.include_uncertain = "true";
      /** @type {AcrossHorses} */
      const answer = await get(`/api/saddles/${saddle.id}/across-horses`, { params: query });
      if (!current()) return;
      showError(section, null);
      showHorses(view, answer);
      showRides(view, answer);
    } catch (error) {
      if (current()) showError(section, error);
    }
  });
}
