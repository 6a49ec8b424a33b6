// Riders' grades against an indicator: scatter of horse-gait points with Pearson's r, Spearman's rho and n.

import { get } from "../api.js";
import { h, page, showError } from "../dom.js";
import { gradeGaitScatter } from "../horse-charts.js";
import { fmt, indicatorInfoOf, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { forIndicator, onFormChange } from "./analysis-common.js";
import { loadPlotly } from "../charts.js";

function stat(term, value, key) {
  return h("div", {}, h("dt", {}, term), h("dd", { dataset: { stat: key } }, value));
}

function interval(low, high) {
  return Number.isFinite(low) && Number.isFinite(high) ? ` (95 % CI ${fmt(low, 2)} to ${fmt(high, 2)})` : "";
}

export async function mountGrades(view) {
  loadPlotly().catch(() => {}); // parse the chart library while the API answers (a chart says if it failed)
  view.append(page("grades"));
  const form = view.querySelector("[data-grades-form]");
  const section = form.closest("section");
  const stats = view.querySelector("[data-grades-stats]");
  const chart = view.querySelector('[data-chart="grades"]');
  await fillOptions(view);

  await onFormChange(form, async ({ gait, indicator }, current) => {
    let c;
    try {
      c = forIndicator(await get("/api/grades/correlation", { params: { gait, indicator } }), indicator) || {};
    } catch (error) {
      if (current()) showError(section, error);
      return;
    }
    if (!current()) return;
    showError(section, null);
    const info = indicatorInfoOf(indicator);
    const r = c.pearson_r ?? c.pearson?.r;
    const rho = c.spearman_rho ?? c.spearman?.rho;
    // Fewer than min_points points: no coefficient is served, the page says how many are needed.
    const withheld = c.withheld_reason || ((c.n ?? 0) < (c.min_points ?? 5)
      ? `needs at least ${c.min_points ?? 5} graded horse-gait pairs to show a correlation` : null);
    const correlation = withheld
      ? [stat("Correlation", withheld, "withheld")]
      : [stat("Pearson r", `${fmt(r, 2)}${interval(c.pearson_ci_low, c.pearson_ci_high)}`, "pearson"),
        stat("Spearman \u03c1", `${fmt(rho, 2)}${interval(c.spearman_ci_low, c.spearman_ci_high)}`, "spearman")];
    stats.replaceChildren(
      stat("n (horse-gait pairs)", String(c.n ?? 0), "n"),
      ...correlation,
      stat("Expected sign", c.expected_sign === -1 ? "negative (lower is more comfortable)"
        : c.expected_sign === 1 ? "positive (higher is more comfortable)" : "none", "expected"));
    gradeGaitScatter(chart, c.points || [], { title: labelText(info.label), unit: prettyUnit(info.unit), label: labelText(info.label) });
  });
}
