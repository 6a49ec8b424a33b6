// Ride similarity: the "rides most alike" panel of the ride page, and the pair view
// (#/compare-rides/:a/:b) with both saddle-point paths overlaid in 3-D and the strides aligned.

import { get } from "../api.js";
import { announce, h, page } from "../dom.js";
import { differencesStrip, emptyChart, loadPlotly, pairPaths3d, strideAlignmentChart } from "../charts.js";
import { fmt, gaitLabel } from "../format.js";
import { poll } from "../poll.js";

export const MARKER_CHOICES = [
  ["saddle", "saddle point S"], ["M1", "marker M1"], ["M2", "marker M2"], ["M3", "marker M3"], ["all", "all markers"],
];
export const SPAN_CHOICES = [["stride", "one mean stride"], ["window", "whole window"]];

function fillSelect(select, choices, value) {
  select.replaceChildren(...choices.map(([v, text]) => h("option", { value: v }, text)));
  if (value && choices.some(([v]) => v === value)) select.value = value;
}

function rideName(ride) {
  return `${ride.horse}, ${gaitLabel(ride.gait)}${ride.ridden_on ? `, ${ride.ridden_on}` : ""} (#${ride.ride_id})`;
}

function pairHref(a, b, markers, span) {
  return `#/compare-rides/${a}/${b}?markers=${encodeURIComponent(markers)}&span=${encodeURIComponent(span)}`;
}

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

/** The "rides most alike" panel of ride `ride` (analysed); returns a function that stops its polling. */
export function mountAlikePanel(view, ride) {
  const panel = view.querySelector("[data-alike-panel]");
  if (!panel) return () => {};
  const form = panel.querySelector("[data-alike-form]");
  const state = panel.querySelector("[data-alike-state]");
  const list = panel.querySelector("[data-alike-list]");
  const error = panel.querySelector("[data-form-error]");
  fillSelect(form.elements.markers, MARKER_CHOICES, "saddle");
  fillSelect(form.elements.span, SPAN_CHOICES, "stride");
  let poller = null;
  let generation = 0;

  const showError = (message) => { error.textContent = message; error.hidden = !message; };

  async function load() {
    const mine = ++generation;
    poller?.stop();
    showError("");
    list.replaceChildren();
    delete list.dataset.markers;
    state.textContent = "Looking up the comparisons\u2026";
    const options = { markers: form.elements.markers.value, span: form.elements.span.value,
                      gait: form.elements.gait.value, limit: 10 };
    poller = poll(async () => {
      let answer;
      try {
        answer = await get(`/api/rides/${ride.id}/similar`, { params: options, withHeaders: true });
      } catch (err) {
        if (mine === generation) { showError(err.message); state.textContent = ""; }
        return false;
      }
      if (mine !== generation) return false;
      if (answer.status === 202) {
        const { job, cached, pairs } = answer.data;
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
      const { items, candidates, not_comparable: skipped } = answer.data;
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

function facts(pair) {
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

/** The pair view: #/compare-rides/:a/:b?markers=...&span=... */
export async function mountRidePair(view, { a, b }, query) {
  loadPlotly({ threeD: true }).catch(() => {}); // parse the chart library while the API answers (a chart says if it failed)
  view.append(page("ride-pair"));
  const form = view.querySelector("[data-pair-form]");
  const state = view.querySelector("[data-pair-state]");
  fillSelect(form.elements.markers, MARKER_CHOICES, query.get("markers") || "saddle");
  fillSelect(form.elements.span, SPAN_CHOICES, query.get("span") || "stride");
  view.querySelector("[data-pair-back]").setAttribute("href", `#/rides/${encodeURIComponent(a)}`);
  view.querySelector("[data-pair-back]").textContent = `#${a}`;
  const paths = view.querySelector('[data-chart="pair-paths"]');
  const alignment = view.querySelector('[data-chart="pair-alignment"]');
  const differences = view.querySelector('[data-chart="pair-differences"]');

  async function load() {
    state.replaceChildren(h("p", {}, "Comparing\u2026"));
    let pair;
    try {
      pair = await get(`/api/rides/${encodeURIComponent(a)}/similar/${encodeURIComponent(b)}`,
        { params: { markers: form.elements.markers.value, span: form.elements.span.value } });
    } catch (error) {
      state.replaceChildren(h("p", { class: "form-error", role: "alert" }, error.message));
      view.querySelector("[data-pair-facts]").replaceChildren();
      emptyChart(paths, "No comparison.");
      emptyChart(alignment, "No comparison.");
      emptyChart(differences, "No comparison.");
      return;
    }
    const names = pair.rides.map(rideName);
    const short = pair.rides.map((r) => `${r.horse} #${r.ride_id}`);
    view.querySelector("[data-pair-title]").textContent = `${pair.rides[0].horse} and ${pair.rides[1].horse} compared`;
    view.querySelector("[data-pair-rides]").replaceChildren(...pair.rides.map((r, i) => h("li", { class: `pair-${i}` },
      h("a", { href: `#/rides/${r.ride_id}` }, names[i]))));
    view.querySelector("[data-pair-facts]").replaceChildren(...facts(pair));
    state.replaceChildren(h("p", { class: "hint" }, pair.cached ? "From the comparison cache." : "Compared just now."));
    pairPaths3d(paths, pair.view.paths_mm, pair.view.strides, short);
    strideAlignmentChart(alignment, pair.view.strides, short);
    differencesStrip(differences, pair.differences);
  }

  form.addEventListener("change", load);
  await load();
  return undefined;
}
