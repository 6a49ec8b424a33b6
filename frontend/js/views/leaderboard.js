// Horses ranked per gait and indicator, most comfortable first (the server ranks; we show).

import { get } from "../api.js";
import { field, h, messageOf, one, page, showError } from "../dom.js";
import { fmt, gaitLabel, indicatorInfoOf, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { onFormChange } from "./analysis-common.js";

/** @typedef {import("../api-types").LeaderboardOut} Leaderboard */

// With no gait asked for, open on the gait with the most ranked rides (rides too uncertain for a decision
// are not ranked): not on a gait whose rides are all too uncertain, as the walk's often are. The answers
// are kept (`answers`, by gait) so the first table needs no second request.
/**
 * @param {HTMLFormElement} form
 * @param {Map<string, Leaderboard>} answers "gait|indicator" -> the ranking
 * @returns {Promise<string | null>}
 */
async function mostRankedGait(form, answers) {
  const gaits = [...field(form, "gait", HTMLSelectElement).options].map((o) => o.value).filter(Boolean);
  const indicator = field(form, "indicator", HTMLSelectElement).value;
  const ranked = await Promise.all(gaits.map(async (gait) => {
    try {
      /** @type {Leaderboard} */
      const answer = await get("/api/leaderboard", { params: { gait, indicator } });
      answers.set(`${gait}|${indicator}`, answer);
      return answer.entries.reduce((total, row) => total + (Number(row.n) || 0), 0);
    } catch (error) {
      console.info(`leaderboard of ${gait} not available:`, messageOf(error));
      return 0;
    }
  }));
  const best = ranked.indexOf(Math.max(...ranked));
  return best >= 0 && ranked[best] > 0 ? gaits[best] : null;
}

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} _params
 * @param {URLSearchParams} query
 */
export async function mountLeaderboard(view, _params, query) {
  view.append(page("leaderboard"));
  const form = one(view, "[data-leaderboard-form]", HTMLFormElement);
  const table = one(view, "[data-leaderboard-table]", HTMLTableElement);
  const empty = one(view, "[data-leaderboard-empty]");
  const note = one(view, "[data-leaderboard-note]");
  const section = /** @type {HTMLElement} */ (form.closest("section"));
  await fillOptions(view);
  for (const name of ["gait", "indicator", "saddle_id"]) {
    const value = query.get(name);
    if (value) field(form, name, HTMLSelectElement).value = value;
  }
  /** @type {Map<string, Leaderboard>} */
  const answers = new Map();
  if (!query.get("gait")) {
    const gait = await mostRankedGait(form, answers);
    if (gait) field(form, "gait", HTMLSelectElement).value = gait;
  }

  const uncertainBox = one(view, "[data-leaderboard-uncertain]");
  if (query.get("include_uncertain") === "true") field(form, "include_uncertain").checked = true;

  await onFormChange(form, async ({ gait, indicator, include_uncertain: includeUncertain, saddle_id: saddleId }, current) => {
    /** @type {Leaderboard} */
    let answer;
    let rows;
    try {
      /** @type {Record<string, string>} */
      const params = { gait, indicator };
      if (saddleId) params.saddle_id = saddleId;
      if (includeUncertain) params.include_uncertain = "true";
      const key = `${gait}|${indicator}`;
      // the plain ranking of a gait mostRankedGait fetched: once, for the first table
      const fetched = Object.keys(params).length === 2 ? answers.get(key) : undefined;
      answer = fetched ?? await get("/api/leaderboard", { params });
      answers.clear();
      rows = answer.entries;
    } catch (error) {
      if (current()) showError(section, error);
      return;
    }
    if (!current()) return;
    showError(section, null);
    const info = indicatorInfoOf(indicator);
    const unit = prettyUnit(info.unit);
    one(view, "[data-value-head]").textContent = unit ? `Mean (${unit})` : "Mean";
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
    const saddle = saddleId ? field(form, "saddle_id", HTMLSelectElement).selectedOptions[0]?.textContent : null;
    empty.textContent = saddle ? `No analysed rides in this gait in the saddle ${saddle} yet.`
      : "No analysed rides in this gait yet.";
    showUncertain(uncertainBox, answer.uncertain ?? [], Boolean(includeUncertain), unit);
  });
}

// Rides too uncertain for a decision: shown, marked, with the reason (issue 27); left out of the
// ranking unless the box is ticked.
/**
 * @param {HTMLElement} box
 * @param {import("../api-types").UncertainRide[]} rides
 * @param {boolean} included
 * @param {string} unit
 */
function showUncertain(box, rides, included, unit) {
  box.hidden = !rides.length;
  if (!rides.length) return;
  one(box, "[data-uncertain-note]").textContent = included
    ? `${rides.length} ride(s) below are too uncertain for a decision; they are counted in the ranking above.`
    : `${rides.length} ride(s) below are too uncertain for a decision and are left out of the ranking above.`;
  one(box, "[data-uncertain-list]").replaceChildren(...rides.map((ride) => h("li",
    { dataset: { uncertainRide: ride.ride_id } },
    h("a", { href: `#/rides/${ride.ride_id}` }, `${ride.horse}, ride ${ride.ride_id}`),
    `: ${fmt(ride.value)}${unit ? ` ${unit}` : ""} (${ride.reason})`)));
}
