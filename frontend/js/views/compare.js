// One horse across gaits, and horses within a gait: bars of the mean with std and min-max spread, each
// saying how many rides stand behind it.

import { get } from "../api.js";
import { field, h, maybeOne, one, page, showError } from "../dom.js";
import { countedBarChart } from "../horse-charts.js";
import { GAITS, gaitLabel, indicatorInfoOf, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { onFormChange } from "./analysis-common.js";
import { loadPlotly } from "../charts.js";

/**
 * Under a chart: how many rides too uncertain for a decision were left out of it (none: nothing said).
 * @param {HTMLElement} chart
 * @param {number | undefined} count
 */
function sayLeftOut(chart, count) {
  let note = maybeOne(/** @type {HTMLElement} */ (chart.parentElement), "[data-left-out]");
  if (!note) {
    note = h("p", { class: "hint", "data-left-out": true });
    chart.after(note);
  }
  note.textContent = count ? `${count} ride${count === 1 ? " is" : "s are"} too uncertain for a decision and left out.` : "";
  note.hidden = !count;
}

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} _params
 * @param {URLSearchParams} query
 */
export async function mountCompare(view, _params, query) {
  loadPlotly().catch(() => {}); // parse the chart library while the API answers (a chart says if it failed)
  view.append(page("compare"));
  const horseForm = one(view, '[data-compare-form="horse"]', HTMLFormElement);
  const gaitForm = one(view, '[data-compare-form="gait"]', HTMLFormElement);
  const horseChart = one(view, '[data-chart="compare-horse"]');
  const gaitChart = one(view, '[data-chart="compare-gait"]');
  await fillOptions(view);
  const asked = { horse: query.get("horse"), saddle: query.get("saddle_id") };
  if (asked.horse) field(horseForm, "horse_id", HTMLSelectElement).value = asked.horse;
  if (asked.saddle) field(gaitForm, "saddle_id", HTMLSelectElement).value = asked.saddle;

  const byHorse = onFormChange(horseForm, async ({ horse_id: horseId, indicator }, current) => {
    const section = /** @type {HTMLElement} */ (horseForm.closest("section"));
    const horsePage = one(section, "[data-compare-horse-page]");
    horsePage.hidden = !horseId;
    if (!horseId) return;
    one(horsePage, "a", HTMLAnchorElement).href = `#/horses/${horseId}`;
    try {
      /** @type {import("../api-types").HorseComparisonOut} */
      const answer = await get(`/api/horses/${horseId}/comparison`, { params: { indicator } });
      if (!current()) return;
      showError(section, null);
      // Gaits in their natural order (walk, trots, canter), not the server's.
      const groups = (answer.indicators[indicator]?.gaits ?? [])
        .map((g) => ({ ...g, label: gaitLabel(g.group) }))
        .sort((a, b) => GAITS.indexOf(a.group) - GAITS.indexOf(b.group));
      const info = indicatorInfoOf(indicator);
      const horse = field(horseForm, "horse_id", HTMLSelectElement).selectedOptions[0]?.textContent ?? "";
      countedBarChart(horseChart, groups, { title: `${horse}: ${labelText(info.label)}`, unit: prettyUnit(info.unit), xTitle: "gait" });
      sayLeftOut(horseChart, answer.uncertain_left_out);
    } catch (error) {
      showError(section, error);
    }
  });

  const byGait = onFormChange(gaitForm, async ({ gait, indicator, saddle_id: saddleId }, current) => {
    const section = /** @type {HTMLElement} */ (gaitForm.closest("section"));
    try {
      /** @type {Record<string, string>} */
      const params = { gait, indicator };
      if (saddleId) params.saddle_id = saddleId;
      /** @type {import("../api-types").ComparisonOut} */
      const answer = await get("/api/comparison", { params });
      if (!current()) return;
      showError(section, null);
      const groups = (answer.indicators[indicator]?.horses ?? []).map((g) => ({ ...g, label: g.horse ?? g.group }));
      const info = indicatorInfoOf(indicator);
      countedBarChart(gaitChart, groups, { title: `${gaitLabel(gait)}: ${labelText(info.label)}`, unit: prettyUnit(info.unit), xTitle: "horse" });
      sayLeftOut(gaitChart, answer.uncertain_left_out);
    } catch (error) {
      showError(section, error);
    }
  });
  await Promise.all([byHorse, byGait]);
}
