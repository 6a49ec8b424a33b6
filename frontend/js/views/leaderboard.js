// Horses ranked per gait and indicator, most comfortable first (the server ranks; we show).

import { get } from "../api.js";
import { h, page, showError } from "../dom.js";
import { fmt, gaitLabel, indicatorInfoOf, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { groupsOf, onFormChange } from "./analysis-common.js";

// With no gait asked for, open on the gait with the most ranked rides (rides too uncertain for a decision
// are not ranked): not on a gait whose rides are all too uncertain, as the walk's often are. The answers
// are kept (`answers`, by gait) so the first table needs no second request.
async function mostRankedGait(form, answers) {
  const gaits = [...form.elements.gait.options].map((o) => o.value).filter(Boolean);
  const indicator = form.elements.indicator.value;
  const ranked = await Promise.all(gaits.map(async (gait) => {
    try {
      const answer = await get("/api/leaderboard", { params: { gait, indicator } });
      answers.set(`${gait}|${indicator}`, answer);
      return groupsOf(answer, indicator).reduce((total, row) => total + (Number(row.n) || 0), 0);
    } catch (error) {
      console.info(`leaderboard of ${gait} not available:`, error.message);
      return 0;
    }
  }));
  const best = ranked.indexOf(Math.max(...ranked));
  return best >= 0 && ranked[best] > 0 ? gaits[best] : null;
}

export async function mountLeaderboard(view, _params, query) {
  view.append(page("leaderboard"));
  const form = view.querySelector("[data-leaderboard-form]");
  const table = view.querySelector("[data-leaderboard-table]");
  const empty = view.querySelector("[data-leaderboard-empty]");
  const note = view.querySelector("[data-leaderboard-note]");
  const section = form.closest("section");
  await fillOptions(view);
  for (const name of ["gait", "indicator", "saddle_id"]) if (query.get(name)) form.elements[name].value = query.get(name);
  const answers = new Map();
  if (!query.get("gait")) {
    const gait = await mostRankedGait(form, answers);
    if (gait) form.elements.gait.value = gait;
  }

  const uncertainBox = view.querySelector("[data-leaderboard-uncertain]");
  if (query.get("include_uncertain") === "true") form.elements.include_uncertain.checked = true;

  await onFormChange(form, async ({ gait, indicator, include_uncertain: includeUncertain, saddle_id: saddleId }, current) => {
    let answer;
    let rows;
    try {
      const params = { gait, indicator };
      if (saddleId) params.saddle_id = saddleId;
      if (includeUncertain) params.include_uncertain = "true";
      const key = `${gait}|${indicator}`;
      // the plain ranking of a gait mostRankedGait fetched: once, for the first table
      const fetched = Object.keys(params).length === 2 ? answers.get(key) : undefined;
      answer = fetched ?? await get("/api/leaderboard", { params });
      answers.clear();
      rows = groupsOf(answer, indicator);
    } catch (error) {
      if (current()) showError(section, error);
      return;
    }
    if (!current()) return;
    showError(section, null);
    const info = indicatorInfoOf(indicator);
    const unit = prettyUnit(info.unit);
    view.querySelector("[data-value-head]").textContent = unit ? `Mean (${unit})` : "Mean";
    const gaitWords = gaitLabel(gait);
    note.textContent = `${gaitWords.charAt(0).toUpperCase()}${gaitWords.slice(1)}, ${labelText(info.label)}: ` +
      `${(answer.better ?? info.better) === "higher" ? "higher" : "lower"} is more comfortable.`;
    table.tBodies[0].replaceChildren(...rows.map((row) => h("tr", { dataset: { horse: row.horse } },
      h("td", { class: "rank" }, String(row.rank)),
      h("th", { scope: "row" }, row.horse_id ? h("a", { href: `#/horses/${row.horse_id}` }, row.horse) : row.horse,
        row.uncertain_rides ? h("span", { class: "uncertain-mark", title: "includes rides too uncertain for a decision" },
          ` (${row.uncertain_rides} uncertain)`) : ""),
      h("td", { class: "num" }, String(row.n)),
      h("td", { class: "num", dataset: { value: row.mean } }, fmt(row.mean)),
      h("td", { class: "num" }, fmt(row.std)),
      h("td", { class: "num" }, fmt(row.min)),
      h("td", { class: "num" }, fmt(row.max)))));
    table.hidden = !rows.length;
    empty.hidden = rows.length > 0;
    const saddle = saddleId ? form.elements.saddle_id.selectedOptions[0]?.textContent : null;
    empty.textContent = saddle ? `No analysed rides in this gait in the saddle ${saddle} yet.`
      : "No analysed rides in this gait yet.";
    showUncertain(uncertainBox, answer.uncertain ?? [], Boolean(includeUncertain), unit);
  });
}

// Rides too uncertain for a decision: shown, marked, with the reason (issue 27); left out of the
// ranking unless the box is ticked.
function showUncertain(box, rides, included, unit) {
  box.hidden = !rides.length;
  if (!rides.length) return;
  box.querySelector("[data-uncertain-note]").textContent = included
    ? `${rides.length} ride(s) below are too uncertain for a decision; they are counted in the ranking above.`
    : `${rides.length} ride(s) below are too uncertain for a decision and are left out of the ranking above.`;
  box.querySelector("[data-uncertain-list]").replaceChildren(...rides.map((ride) => h("li",
    { dataset: { uncertainRide: ride.ride_id } },
    h("a", { href: `#/rides/${ride.ride_id}` }, `${ride.horse}, ride ${ride.ride_id}`),
    `: ${fmt(ride.value)}${unit ? ` ${unit}` : ""} (${ride.reason})`)));
}
