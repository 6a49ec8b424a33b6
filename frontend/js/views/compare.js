// One horse across gaits, and horses within a gait: bars of the mean with std and min-max spread, each
// saying how many rides stand behind it.

import { get } from "../api.js";
import { h, page, showError } from "../dom.js";
import { countedBarChart } from "../horse-charts.js";
import { GAITS, gaitLabel, indicatorInfoOf, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { groupsOf, onFormChange } from "./analysis-common.js";
import { loadPlotly } from "../charts.js";

/** Under a chart: how many rides too uncertain for a decision were left out of it (none: nothing said). */
function sayLeftOut(chart, count) {
  let note = chart.parentElement.querySelector("[data-left-out]");
  if (!note) {
    note = h("p", { class: "hint", "data-left-out": true });
    chart.after(note);
  }
  note.textContent = count ? `${count} ride${count === 1 ? " is" : "s are"} too uncertain for a decision and left out.` : "";
  note.hidden = !count;
}

export async function mountCompare(view, _params, query) {
  loadPlotly().catch(() => {}); // parse the chart library while the API answers (a chart says if it failed)
  view.append(page("compare"));
  const horseForm = view.querySelector('[data-compare-form="horse"]');
  const gaitForm = view.querySelector('[data-compare-form="gait"]');
  const horseChart = view.querySelector('[data-chart="compare-horse"]');
  const gaitChart = view.querySelector('[data-chart="compare-gait"]');
  await fillOptions(view);
  if (query.get("horse")) horseForm.elements.horse_id.value = query.get("horse");
  if (query.get("saddle_id")) gaitForm.elements.saddle_id.value = query.get("saddle_id");

  const byHorse = onFormChange(horseForm, async ({ horse_id: horseId, indicator }, current) => {
    const section = horseForm.closest("section");
    const horsePage = section.querySelector("[data-compare-horse-page]");
    horsePage.hidden = !horseId;
    if (!horseId) return;
    horsePage.querySelector("a").href = `#/horses/${horseId}`;
    try {
      const answer = await get(`/api/horses/${horseId}/comparison`, { params: { indicator } });
      if (!current()) return;
      showError(section, null);
      // Gaits in their natural order (walk, trots, canter), not the server's.
      const groups = groupsOf(answer, indicator)
        .map((g) => ({ ...g, label: gaitLabel(g.group ?? g.gait) }))
        .sort((a, b) => GAITS.indexOf(a.group ?? a.gait) - GAITS.indexOf(b.group ?? b.gait));
      const info = indicatorInfoOf(indicator);
      const horse = horseForm.elements.horse_id.selectedOptions[0]?.textContent ?? "";
      countedBarChart(horseChart, groups, { title: `${horse}: ${labelText(info.label)}`, unit: prettyUnit(info.unit), xTitle: "gait" });
      sayLeftOut(horseChart, answer.uncertain_left_out);
    } catch (error) {
      showError(section, error);
    }
  });

  const byGait = onFormChange(gaitForm, async ({ gait, indicator, saddle_id: saddleId }, current) => {
    const section = gaitForm.closest("section");
    try {
      const params = { gait, indicator };
      if (saddleId) params.saddle_id = saddleId;
      const answer = await get("/api/comparison", { params });
      if (!current()) return;
      showError(section, null);
      const groups = groupsOf(answer, indicator).map((g) => ({ ...g, label: g.horse ?? g.group }));
      const info = indicatorInfoOf(indicator);
      countedBarChart(gaitChart, groups, { title: `${gaitLabel(gait)}: ${labelText(info.label)}`, unit: prettyUnit(info.unit), xTitle: "horse" });
      sayLeftOut(gaitChart, answer.uncertain_left_out);
    } catch (error) {
      showError(section, error);
    }
  });
  await Promise.all([byHorse, byGait]);
}
