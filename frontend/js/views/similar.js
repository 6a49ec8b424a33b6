// Ride similarity: the "rides most alike" panel of the ride page, and the pair view
// (#/compare-rides/:a/:b) with both saddle-point paths overlaid in 3-D and the strides aligned.

import { get } from "../api.js";
import { announce, field, h, maybeOne, messageOf, one, page } from "../dom.js";
import { differencesStrip, emptyChart, loadPlotly, pairPaths3d, strideAlignmentChart } from "../charts.js";
import { fmt, gaitLabel } from "../format.js";
import { poll } from "../poll.js";

/** @typedef {import("../api-types").RideSummary} RideSummary */
/** @typedef {{markers: string, span: string, gait: string, limit: number}} AlikeOptions */

/** @type {[string, string][]} */
const MARKER_CHOICES = [
  ["saddle", "saddle point S"], ["M1", "marker M1"], ["M2", "marker M2"], ["M3", "marker M3"], ["all", "all markers"],
];
/** @type {[string, string][]} */
const SPAN_CHOICES = [["stride", "one mean stride"], ["window", "whole window"]];

/**
 * @param {HTMLSelectElement} select
 * @param {[string, string][]} choices values and their words
 * @param {string} value the one chosen, where it is one
 */
function fillSelect(select, choices, value) {
  select.replaceChildren(...choices.map(([v, text]) => h("option", { value: v }, text)));
  if (value && choices.some(([v]) => v === value)) select.value = value;
}

/** @param {RideSummary} ride */
function rideName(ride) {
  return `${ride.horse}, ${gaitLabel(ride.gait)}${ride.ridden_on ? `, ${ride.ridden_on}` : ""} (#${ride.ride_id})`;
}

/**
 * @param {number | string} a
 * @param {number | string} b
 * @param {string} markers
 * @param {string} span
 */
function pairHref(a, b, markers, span) {
  return `#/compare-rides/${a}/${b}?markers=${encodeURIComponent(markers)}&span=${encodeURIComponent(span)}`;
}

/**
 * @param {number} rideId
 * @param {import("../api-types").AlikeEntry} item
 * @param {AlikeOptions} options
 */
function alikeItem(rideId, item, options) {
  const { ride, similarity } = item;
  const percent = Math.round(similarity * 100);
  return h("li", { class: "alike-item", dataset: { rideId: String(ride.ride_id), similarity: String(similarity) } },
    h("span", { class: "alike-rank" }, `${item.rank}.`),
    h("span", { class: "alike-what" },
      h("a", { href: `#/rides/${ride.ride_id}` }, ride.horse),
      h("span", { class: "hint alike-detail" },
        `${gaitLabel(ride.gait)}${ride.ridden_on ? ` \u00b7 ${ride.ridden_on}` : ""}`)),
    h("span", { class: "alike-score" },
      h("meter", { min: "0", max: "1", value: String(similarity), "aria-label": `similarity ${percent} percent` }),
      h("span", { class: "num", "data-value": String(similarity) }, fmt(similarity))),
    h("a", { class: "alike-compare", href: pairHref(rideId, ride.ride_id, options.markers, options.span),
             dataset: { pairLink: "" } }, "Compare"));
}

/**
 * The "rides most alike" panel of ride `ride` (analysed); returns a function that stops its polling.
 * @param {HTMLElement} view
 * @param {import("../api-types").RideOut} ride
 * @returns {() => void}
 */
export function mountAlikePanel(view, ride) {
  const panel = maybeOne(view, "[data-alike-panel]");
  if (!panel) return () => {};
  const form = one(panel, "[data-alike-form]", HTMLFormElement);
  const state = one(panel, "[data-alike-state]");
  const list = one(panel, "[data-alike-list]");
  const error = one(panel, "[data-form-error]");
  const select = (/** @type {string} */ name) => field(form, name, HTMLSelectElement);
  fillSelect(select("markers"), MARKER_CHOICES, "saddle");
  fillSelect(select("span"), SPAN_CHOICES, "stride");
  /** @type {import("../poll.js").Poller | null} */
  let poller = null;
  let generation = 0;

  const showError = (/** @type {string} */ message) => { error.textContent = message; error.hidden = !message; };

  async function load() {
    const mine = ++generation;
    poller?.stop();
    showError("");
    list.replaceChildren();
    delete list.dataset.markers;
    state.textContent = "Looking up the comparisons\u2026";
    /** @type {AlikeOptions} */
    const options = { markers: select("markers").value, span: select("span").value,
                      gait: select("gait").value, limit: 10 };
    poller = poll(async () => {
      /** @type {{status: number, data: import("../api-types").AlikeOut | import("../api-types").PendingOut}} 202: PendingOut */
      let answer;
      try {
        answer = await get(`/api/rides/${ride.id}/similar`, { params: options, withHeaders: true });
      } catch (err) {
        if (mine === generation) { showError(messageOf(err)); state.textContent = ""; }
        return false;
      }
      if (mine !== generation) return false;
      if (answer.status === 202) {
        const { job, cached, pairs } = /** @type {import("../api-types").PendingOut} */ (answer.data);
        if (job.status === "failed" || job.status === "cancelled") {
          showError(`The comparison job #${job.id} ${job.status}${job.error ? `: ${job.error}` : ""}`);
          state.textContent = "";
          return false;
        }
        state.textContent = `Comparing with ${pairs} rides (${cached} already compared; job #${job.id} `
          + `${job.status}, ${Math.round((job.progress ?? 0) * 100)} %)\u2026`;
        list.setAttribute("aria-busy", "true");
        return 1000;
      }
      const { items, candidates, not_comparable: skipped } = /** @type {import("../api-types").AlikeOut} */ (answer.data);
      list.removeAttribute("aria-busy");
      list.replaceChildren(...items.map((item) => alikeItem(ride.id, item, options)));
      Object.assign(list.dataset, { markers: options.markers, span: options.span, gait: options.gait });
      const scope = options.gait === "any" ? "in any gait" : `in ${gaitLabel(ride.gait)}`;
      state.textContent = items.length
        ? `The ${items.length} of ${candidates} analysed rides ${scope} whose motion is most like this ride's`
          + ` (1 = the same motion).${skipped.length ? ` ${skipped.length} could not be compared.` : ""}`
        : `No other analysed ride ${scope} to compare with yet.`;
      announce(state.textContent);
      return false;
    });
  }

  form.addEventListener("change", load);
  load();
  return () => { generation += 1; poller?.stop(); };
}

/** @param {import("../api-types").SimilarityPairOut} pair */
function facts(pair) {
  /** @type {[string, string][]} */
  const rows = [["Similarity", pair.similarity === null ? "not comparable" : fmt(pair.similarity)],
    ["Measure", pair.measure ?? "\u2013"]];
  for (const [name, value] of Object.entries(pair.measures || {})) {
    if (typeof value === "number") rows.push([name.replaceAll("_", " "), fmt(value)]);
  }
  if (pair.view?.strides) rows.push(["Phase shift of the second stride", `${fmt(pair.view.strides.shift_phase * 100, 3)} % of a stride`]);
  const diff = pair.differences;
  if (diff) {
    const k = diff.most_different_stretch;
    const stretch = `${Math.round((k / diff.stretches) * 100)}-${Math.round(((k + 1) / diff.stretches) * 100)} %`;
    rows.push(["Differ most", `${diff.most_different_marker}, ${stretch} of the stride`]);
  }
  if (pair.reason) rows.push(["Why not comparable", pair.reason]);
  return rows.flatMap(([term, value]) => [h("dt", {}, term), h("dd", { dataset: { fact: term } }, String(value))]);
}

/**
 * The pair view: #/compare-rides/:a/:b?markers=...&span=...
 * @param {HTMLElement} view
 * @param {Record<string, string>} params the two rides' ids
 * @param {URLSearchParams} query
 */
export async function mountRidePair(view, { a, b }, query) {
  loadPlotly({ threeD: true }).catch(() => {}); // parse the chart library while the API answers (a chart says if it failed)
  view.append(page("ride-pair"));
  const form = one(view, "[data-pair-form]", HTMLFormElement);
  const state = one(view, "[data-pair-state]");
  const select = (/** @type {string} */ name) => field(form, name, HTMLSelectElement);
  fillSelect(select("markers"), MARKER_CHOICES, query.get("markers") || "saddle");
  fillSelect(select("span"), SPAN_CHOICES, query.get("span") || "stride");
  one(view, "[data-pair-back]").setAttribute("href", `#/rides/${encodeURIComponent(a)}`);
  one(view, "[data-pair-back]").textContent = `#${a}`;
  const paths = one(view, '[data-chart="pair-paths"]');
  const alignment = one(view, '[data-chart="pair-alignment"]');
  const differences = one(view, '[data-chart="pair-differences"]');

  async function load() {
    state.replaceChildren(h("p", {}, "Comparing\u2026"));
    /** @type {import("../api-types").SimilarityPairOut} */
    let pair;
    try {
      pair = await get(`/api/rides/${encodeURIComponent(a)}/similar/${encodeURIComponent(b)}`,
        { params: { markers: select("markers").value, span: select("span").value } });
    } catch (error) {
      state.replaceChildren(h("p", { class: "form-error", role: "alert" }, messageOf(error)));
      one(view, "[data-pair-facts]").replaceChildren();
      emptyChart(paths, "No comparison.");
      emptyChart(alignment, "No comparison.");
      emptyChart(differences, "No comparison.");
      return;
    }
    const names = pair.rides.map(rideName);
    const short = pair.rides.map((r) => `${r.horse} #${r.ride_id}`);
    one(view, "[data-pair-title]").textContent = `${pair.rides[0].horse} and ${pair.rides[1].horse} compared`;
    one(view, "[data-pair-rides]").replaceChildren(...pair.rides.map((r, i) => h("li", { class: `pair-${i}` },
      h("a", { href: `#/rides/${r.ride_id}` }, names[i]))));
    one(view, "[data-pair-facts]").replaceChildren(...facts(pair));
    state.replaceChildren(h("p", { class: "hint" }, pair.cached ? "From the comparison cache." : "Compared just now."));
    pairPaths3d(paths, pair.view.paths_mm, pair.view.strides, short);
    strideAlignmentChart(alignment, pair.view.strides, short);
    differencesStrip(differences, pair.differences);
  }

  form.addEventListener("change", load);
  await load();
  return undefined;
}
