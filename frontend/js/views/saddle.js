// One saddle across the club's horses (#/saddles/:id): its details, per horse and gait the rides in it
// with each indicator's mean and 95 % interval, and its analysed rides, newest first. Rides too
// uncertain for a decision are listed (marked) but counted only when asked.

import { get } from "../api.js";
import { h, page, showError } from "../dom.js";
import { fmt, gaitLabel, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { meanIntervalText, saddleTypeText } from "../saddle-words.js";
import { onFormChange } from "./analysis-common.js";

function showDetails(view, saddle) {
  view.querySelector("[data-saddle-name]").textContent = saddle.name;
  document.title = `${saddle.name} \u2013 SaddleScope`;
  const item = (term, value, key) => h("div", {}, h("dt", {}, term), h("dd", { dataset: { profile: key } }, value));
  view.querySelector("[data-saddle-profile]").replaceChildren(
    item("Maker", saddle.maker || "\u2013", "maker"),
    item("Type", saddleTypeText(saddle.saddle_type), "type"),
    item("Tree width", saddle.tree_width || "\u2013", "tree_width"),
    item("Rides", String(saddle.rides), "rides"),
    ...(saddle.notes ? [item("Notes", saddle.notes, "notes")] : []));
}

function headCells(answer, first) {
  return [...first.map((text) => h("th", { scope: "col" }, text)),
    ...Object.keys(answer.labels).map((key) => h("th", { scope: "col", class: "num" },
      `${labelText(answer.labels[key])} (${prettyUnit(answer.units[key])})`))];
}

function showHorses(view, answer) {
  const table = view.querySelector("[data-saddle-horses]");
  const keys = Object.keys(answer.labels);
  table.tHead.rows[0].replaceChildren(...headCells(answer, ["Horse", "Gait", "Rides"]));
  table.tBodies[0].replaceChildren(...answer.horses.map((row) => h("tr", { dataset: { horseId: row.horse_id } },
    h("th", { scope: "row" }, h("a", { href: `#/horses/${row.horse_id}` }, row.horse)),
    h("td", {}, gaitLabel(row.gait)),
    h("td", { class: "num" }, String(row.rides)),
    ...keys.map((key) => h("td", { class: "num" }, meanIntervalText(row.indicators[key]))))));
  table.hidden = !answer.horses.length;
  view.querySelector("[data-saddle-horses-empty]").hidden = answer.horses.length > 0;
  view.querySelector("[data-saddle-method]").textContent =
    `Each value: the mean of the rides with its 95 % interval in brackets. ${answer.method}`;
}

function showRides(view, answer) {
  const table = view.querySelector("[data-saddle-rides]");
  const keys = Object.keys(answer.labels);
  table.tHead.rows[0].replaceChildren(...headCells(answer, ["Date", "Horse", "Rider", "Gait"]));
  table.tBodies[0].replaceChildren(...answer.rides.map((ride) => h("tr", { dataset: { rideId: ride.ride_id } },
    h("th", { scope: "row" }, h("a", { href: `#/rides/${ride.ride_id}` }, ride.date ?? `ride #${ride.ride_id}`),
      ride.uncertain_reason ? h("span", { class: "badge", title: ride.uncertain_reason }, " too uncertain") : null),
    h("td", {}, ride.horse), h("td", {}, ride.rider), h("td", {}, gaitLabel(ride.gait)),
    ...keys.map((key) => h("td", { class: "num" }, fmt(ride.indicators[key]))))));
}

export async function mountSaddle(view, params) {
  view.append(page("saddle"));
  let saddle;
  try {
    saddle = await get(`/api/saddles/${params.id}`);
  } catch (error) {
    view.querySelector("[data-saddle-name]").textContent = "Saddle not found";
    showError(view.querySelector("[data-saddle-page-error]"), error);
    for (const panel of view.querySelectorAll("section.panel")) panel.hidden = true;
    return;
  }
  showDetails(view, saddle);
  const form = view.querySelector("[data-saddle-form]");
  await fillOptions(form);
  const section = form.closest("section");
  await onFormChange(form, async ({ gait, include_uncertain: includeUncertain }, current) => {
    try {
      const query = {};
      if (gait) query.gait = gait;
      if (includeUncertain) query.include_uncertain = "true";
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
