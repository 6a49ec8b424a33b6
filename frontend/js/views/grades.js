// Riders' grades against an indicator: scatter of horse-gait points with Pearson's r, Spearman's rho and n.

import { get } from "../api.js";
import { h, one, page, showError } from "../dom.js";
import { gradeGaitScatter } from "../horse-charts.js";
import { fmt, indicatorInfoOf, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { onFormChange } from "./analysis-common.js";
import { loadPlotly } from "../charts.js";

/**
 * One indicator's entry of GET /api/grades/correlation (CorrelationOut.indicators[key]): the schema says only
 * `object`, so the fields this page reads are named here, as
 * saddlescope.services.comparisons.analytics.grade_correlation_report writes them.
 * @typedef {object} Correlation
 * @property {number} [n] horse-gait points
 * @property {number | null} [pearson_r]
 * @property {number | null} [pearson_ci_low]
 * @property {number | null} [pearson_ci_high]
 * @property {number | null} [spearman_rho]
 * @property {number | null} [spearman_ci_low]
 * @property {number | null} [spearman_ci_high]
 * @property {-1 | 0 | 1} [expected_sign]
 * @property {number} [min_points]
 * @property {string | null} [withheld_reason]
 * @property {import("../horse-charts.js").GradePoint[]} [points]
 */

/**
 * @param {string} term
 * @param {string} value
 * @param {string} key
 */
function stat(term, value, key) {
  return h("div", {}, h("dt", {}, term), h("dd", { dataset: { stat: key } }, value));
}

/**
 * @param {number | null | undefined} low
 * @param {number | null | undefined} high
 */
function interval(low, high) {
  return Number.isFinite(low) && Number.isFinite(high) ? ` (95 % CI ${fmt(low, 2)} to ${fmt(high, 2)})` : "";
}

/** @param {HTMLElement} view */
export async function mountGrades(view) {
  loadPlotly().catch(() => {}); // parse the chart library while the API answers (a chart says if it failed)
  view.append(page("grades"));
  const form = one(view, "[data-grades-form]", HTMLFormElement);
  const section = /** @type {HTMLElement} */ (form.closest("section"));
  const stats = one(view, "[data-grades-stats]");
  const chart = one(view, '[data-chart="grades"]');
  await fillOptions(view);

  await onFormChange(form, async ({ gait, indicator }, current) => {
    /** @type {Correlation} */
    let c;
    try {
      /** @type {import("../api-types").CorrelationOut} */
      const answer = await get("/api/grades/correlation", { params: { gait, indicator } });
      c = answer.indicators[indicator] ?? {};
    } catch (error) {
      if (current()) showError(section, error);
      return;
    }
    if (!current()) return;
    showError(section, null);
    const info = indicatorInfoOf(indicator);
    const r = c.pearson_r;
    const rho = c.spearman_rho;
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
