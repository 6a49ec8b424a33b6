// The horse page (#/horses/:id): its profile (editable by members), its rides page by page, its
// indicators across gaits (thesis Figs 8.29-8.32), a trend per gait against the horse's own normal
// band, its saddles compared (mean and 95 % interval per saddle, and in words whether two differ
// beyond the uncertainty), and any two of its rides side by side with the % difference of each indicator.

import { get, getAll, itemsOf, patch } from "../api.js";
import { all, busy, field, fill, h, one, page, showError } from "../dom.js";
import { countedBarChart, trendChart } from "../horse-charts.js";
import { distanceText, durationText, fmt, GAITS, gaitLabel, indicatorInfoOf, labelText, prettyUnit } from "../format.js";
import { fillOptions } from "../options.js";
import { can } from "../session.js";
import { shareControl } from "../share.js";
import { onFormChange } from "./analysis-common.js";
import { meanIntervalText } from "../saddle-words.js";
import { loadPlotly } from "../charts.js";

/** @typedef {import("../api-types").HorseOut} HorseOut */
/** @typedef {import("../api-types").RideOut} RideOut */
/** @typedef {import("../api-types").GroupStats & {gait: string, label: string}} GaitGroup a gait's bar */

const RIDES_PER_PAGE = 10;
const INCH_M = 0.0254;

/**
 * 1.5748 -> "15.2 hh": hands, and inches after the point (0-3).
 * @param {number} heightM
 */
function handsText(heightM) {
  const inches = Math.round(heightM / INCH_M);
  return `${Math.floor(inches / 4)}.${inches % 4} hh`;
}

/** @param {number | null} heightM */
function heightText(heightM) {
  return heightM !== null && Number.isFinite(heightM) ? `${heightM.toFixed(2)} m (${handsText(heightM)})` : "\u2013";
}

/** @param {RideOut} ride */
function rideLabel(ride) {
  return `${ride.ridden_on ?? "undated"} \u00b7 ${gaitLabel(ride.gait)} \u00b7 #${ride.id}`;
}

/**
 * @param {HTMLElement} view
 * @param {HorseOut} horse
 */
function showProfile(view, horse) {
  one(view, "[data-horse-name]").textContent = horse.name;
  document.title = `${horse.name} \u2013 SaddleScope`;
  /** @type {(term: string, value: string, key: string) => HTMLElement} */
  const item = (term, value, key) => h("div", {}, h("dt", {}, term), h("dd", { dataset: { profile: key } }, value));
  one(view, "[data-horse-profile]").replaceChildren(
    item("Breed", horse.breed || "\u2013", "breed"),
    item("Born", horse.birth_year ? String(horse.birth_year) : "\u2013", "birth_year"),
    item("Height at the withers", heightText(horse.height_withers_m), "height"));
}

/**
 * @param {HTMLElement} view
 * @param {HorseOut} horse
 * @param {(horse: HorseOut) => void} onSaved
 */
function setUpProfileForm(view, horse, onSaved) {
  const form = one(view, "[data-horse-form]", HTMLFormElement);
  if (!can(form.dataset.permission ?? "")) return; // stays hidden: the API would answer 403
  form.hidden = false;
  const fill = (/** @type {HorseOut} */ current) => {
    field(form, "name").value = current.name;
    field(form, "breed").value = current.breed ?? "";
    field(form, "birth_year").value = String(current.birth_year ?? "");
    field(form, "height_withers_m").value = current.height_withers_m !== null && Number.isFinite(current.height_withers_m)
      ? current.height_withers_m.toFixed(2) : "";
  };
  fill(horse);
  form.addEventListener("submit", (event) => {
    event.preventDefault();
    const saved = one(form, "[data-horse-saved]");
    saved.textContent = "";
    const text = (/** @type {string} */ name) => field(form, name).value.trim();
    const body = {
      name: text("name"),
      breed: text("breed") || null,
      birth_year: text("birth_year") ? Number.parseInt(text("birth_year"), 10) : null,
      // Sent as typed: the API understands "1.62", "162 cm" and "15.2 hh" and explains anything else.
      height_withers_m: text("height_withers_m") || null,
    };
    busy(form, async () => {
      try {
        /** @type {HorseOut} */
        const updated = await patch(`/api/horses/${horse.id}`, body);
        showError(form, null);
        fill(updated);
        onSaved(updated);
        saved.textContent = "Saved.";
      } catch (error) {
        showError(form, error);
      }
    });
  });
}

/** @param {RideOut} ride */
function rideRow(ride) {
  const wb = ride.indicators?.acc_y_wb_rms;
  return h("tr", { dataset: { rideId: ride.id } },
    h("td", {}, h("a", { href: `#/rides/${ride.id}` }, ride.ridden_on ?? `ride #${ride.id}`)),
    h("td", {}, gaitLabel(ride.gait)),
    h("td", {}, ride.rider_name),
    h("td", {}, ride.status),
    h("td", { class: "num", dataset: { value: wb ?? "" } }, fmt(wb)));
}

/**
 * @param {HTMLElement} view
 * @param {string} horseId
 */
function setUpRides(view, horseId) {
  const table = one(view, "[data-horse-rides]", HTMLTableElement);
  const empty = one(view, "[data-horse-rides-empty]");
  const prev = one(view, "[data-page-prev]", HTMLButtonElement);
  const next = one(view, "[data-page-next]", HTMLButtonElement);
  const info = one(view, "[data-page-info]");
  let offset = 0;
  const load = async () => {
    /** @type {import("../api-types").Page_RideOut_} */
    const answer = await get("/api/rides", { params: { horse_id: horseId, limit: RIDES_PER_PAGE, offset, sort: "-ridden_on" } });
    const rides = itemsOf(answer);
    const { total } = answer;
    table.tBodies[0].replaceChildren(...rides.map(rideRow));
    table.hidden = !rides.length;
    empty.hidden = rides.length > 0;
    info.textContent = total ? `${offset + 1}\u2013${offset + rides.length} of ${total}` : "";
    prev.disabled = offset === 0;
    next.disabled = offset + rides.length >= total;
    prev.hidden = next.hidden = total <= RIDES_PER_PAGE;
  };
  prev.addEventListener("click", () => { offset = Math.max(0, offset - RIDES_PER_PAGE); load(); });
  next.addEventListener("click", () => { offset += RIDES_PER_PAGE; load(); });
  return load();
}

/**
 * @param {HTMLElement} view
 * @param {string} horseId
 * @param {(groups: GaitGroup[]) => void} [onCounts]
 */
function setUpGaits(view, horseId, onCounts) {
  const form = one(view, "[data-horse-gaits-form]", HTMLFormElement);
  const chart = one(view, '[data-chart="horse-gaits"]');
  const section = /** @type {HTMLElement} */ (form.closest("section"));
  return onFormChange(form, async ({ indicator }, current) => {
    try {
      /** @type {import("../api-types").HorseComparisonOut} */
      const answer = await get(`/api/horses/${horseId}/comparison`, { params: { indicator } });
      if (!current()) return;
      showError(section, null);
      const groups = (answer.indicators[indicator]?.gaits ?? [])
        .map((g) => ({ ...g, gait: g.group, label: gaitLabel(g.group) }))
        .sort((a, b) => GAITS.indexOf(a.gait) - GAITS.indexOf(b.gait));
      onCounts?.(groups);
      const info = indicatorInfoOf(indicator);
      countedBarChart(chart, groups, { title: labelText(info.label), unit: prettyUnit(info.unit), xTitle: "gait" });
      const left = answer.uncertain_left_out ?? 0;
      const note = one(section, "[data-gaits-left-out]");
      note.textContent = left ? `${left} ride${left === 1 ? " is" : "s are"} too uncertain for a decision and left out.` : "";
      note.hidden = !left;
    } catch (error) {
      if (current()) showError(section, error);
    }
  });
}

/**
 * @param {HTMLElement} view
 * @param {string} horseId
 */
function setUpTrend(view, horseId) {
  const form = one(view, "[data-horse-trend-form]", HTMLFormElement);
  const chart = one(view, '[data-chart="horse-trend"]');
  const note = one(view, "[data-trend-note]");
  const section = /** @type {HTMLElement} */ (form.closest("section"));
  return onFormChange(form, async ({ gait, indicator }, current) => {
    try {
      /** @type {import("../api-types").TrendOut} */
      const trend = await get(`/api/horses/${horseId}/trend`, { params: { gait, indicator } });
      if (!current()) return;
      showError(section, null);
      const info = indicatorInfoOf(indicator);
      trendChart(chart, trend.points, { title: `${gaitLabel(gait)}: ${labelText(info.label)}`, unit: prettyUnit(info.unit), gait, band: trend.band });
      const n = trend.points.length;
      const banded = trend.points.filter((p) => p.band).length;
      const outside = trend.points.filter((p) => p.outside).length;
      const left = trend.uncertain_left_out ?? 0;
      const leftText = left ? ` ${left} ride${left === 1 ? " is" : "s are"} too uncertain for a decision and not shown.` : "";
      const band = trend.band;
      // Which band is drawn, from how many rides, and how sure its edges are (issue 37).
      const bandText = band
        ? `Shaded: the normal band (mean \u00b1 2 SD) ${band.reason}; its edges are uncertain by about \u00b1${fmt((band.low_interval_95[1] - band.low_interval_95[0]) / 2, 2)}${info.unit ? ` ${prettyUnit(info.unit)}` : ""} (fainter strips, 95 %).`
        : `No band yet: it needs ${trend.min_own_rides} rides of this horse, or of the club's other horses, in ${gaitLabel(gait)}.`;
      const flagged = banded
        ? ` ${outside} of the ${banded} rides with enough earlier rides lie outside the band of those before them.` : "";
      note.textContent = !n ? "" : `${n} ride${n === 1 ? "" : "s"} in ${gaitLabel(gait)}. ${bandText}${flagged}` + leftText;
    } catch (error) {
      if (current()) showError(section, error);
    }
  });
}

/**
 * @param {HTMLElement} view
 * @param {string} horseId
 */
function setUpSaddles(view, horseId) {
  const form = one(view, "[data-horse-saddles-form]", HTMLFormElement);
  const table = one(view, "[data-saddles-table]", HTMLTableElement);
  const verdicts = one(view, "[data-saddles-verdicts]");
  const empty = one(view, "[data-saddles-empty]");
  const method = one(view, "[data-saddles-method]");
  const section = /** @type {HTMLElement} */ (form.closest("section"));
  return onFormChange(form, async ({ gait }, current) => {
    /** @type {import("../api-types").HorseSaddlesOut} */
    let answer;
    try {
      answer = await get(`/api/horses/${horseId}/saddles`, { params: { gait } });
    } catch (error) {
      if (current()) showError(section, error);
      return;
    }
    if (!current()) return;
    showError(section, null);
    const keys = Object.keys(answer.labels);
    /** @type {HTMLTableSectionElement} */ (table.tHead).rows[0].replaceChildren(h("th", { scope: "col" }, "Saddle"), h("th", { scope: "col", class: "num" }, "Rides"),
      ...keys.map((key) => h("th", { scope: "col", class: "num" },
        `${labelText(answer.labels[key])} (${prettyUnit(answer.units[key])})`)));
    table.tBodies[0].replaceChildren(...answer.saddles.map((row) => h("tr", { dataset: { saddleId: row.saddle_id } },
      h("th", { scope: "row" }, h("a", { href: `#/saddles/${row.saddle_id}` }, row.saddle)),
      h("td", { class: "num" }, String(row.rides)),
      ...keys.map((key) => h("td", { class: "num", dataset: { key } }, meanIntervalText(row.indicators[key]))))));
    table.hidden = !answer.saddles.length;
    // The headline comparison (the first indicator, W_b r.m.s.) of each pair; the others folded below it.
    const item = (/** @type {import("../api-types").SaddleDifference} */ d) => h("li", { dataset: { indicator: d.indicator, exceeds: String(d.exceeds_uncertainty ?? "unknown") } },
      d.sentence);
    const headline = answer.differences.filter((d) => d.indicator === keys[0]);
    const others = answer.differences.filter((d) => d.indicator !== keys[0]);
    verdicts.replaceChildren(...headline.map(item));
    if (others.length) {
      verdicts.append(h("li", { class: "more" }, h("details", {}, h("summary", {}, "The other indicators"),
        h("ul", {}, ...others.map(item)))));
    }
    /** @type {string[]} */
    const notes = [];
    if (answer.saddles.length < 2) {
      notes.push(answer.saddles.length
        ? `Only one saddle recorded on this horse in ${gaitLabel(gait)}: record the saddle of each ride to compare.`
        : `No analysed ride of this horse in ${gaitLabel(gait)} names its saddle yet: set it in a ride's details.`);
    }
    if (answer.without_saddle) notes.push(`${answer.without_saddle} analysed ride${answer.without_saddle === 1 ? "" : "s"} without a saddle recorded.`);
    if (answer.uncertain_left_out) notes.push(`${answer.uncertain_left_out} ride${answer.uncertain_left_out === 1 ? " is" : "s are"} too uncertain for a decision and not counted.`);
    empty.textContent = notes.join(" ");
    empty.hidden = !notes.length;
    method.textContent = `In brackets: the 95 % interval of each mean. ${answer.method}`;
  });
}

/** @param {import("../api-types").PairIndicator} row */
function differenceCell(row) {
  const pct = row.difference_percent;
  if (pct === null || !Number.isFinite(pct)) return h("td", { class: "num" }, "\u2013");
  // Below 0.05 % the two rides agree to the digits shown (rounding noise reads as 0 %).
  if (Math.abs(pct) < 0.05) return h("td", { class: "num", dataset: { value: pct, difference: "" } }, "0 %");
  // Which way is more comfortable decides the colour; indicators without a direction stay neutral.
  const better = row.better === "lower" ? pct < 0 : row.better === "higher" ? pct > 0 : null;
  const cls = `num${pct === 0 || better === null ? "" : better ? " better" : " worse"}`;
  const sign = pct > 0 ? "+" : "";
  return h("td", { class: cls, dataset: { value: pct, difference: "" } }, `${sign}${fmt(pct, 2)} %`);
}

/**
 * @param {HTMLElement} view
 * @param {string} horseId
 */
async function setUpPair(view, horseId) {
  const form = one(view, "[data-horse-pair-form]", HTMLFormElement);
  const table = one(view, "[data-pair-table]", HTMLTableElement);
  const empty = one(view, "[data-pair-empty]");
  const section = /** @type {HTMLElement} */ (form.closest("section"));
  /** @type {RideOut[]} */
  const rides = await getAll("/api/rides", { horse_id: horseId, status: "analysed", sort: "-ridden_on" });
  const options = rides.map((ride) => h("option", { value: ride.id }, rideLabel(ride)));
  const [first, second] = [field(form, "a", HTMLSelectElement), field(form, "b", HTMLSelectElement)];
  first.replaceChildren(...options.map((o) => o.cloneNode(true)));
  second.replaceChildren(...options);
  if (rides.length < 2) {
    form.hidden = true;
    empty.hidden = false;
    return;
  }
  first.value = String(rides[1].id); // the second newest against the newest
  second.value = String(rides[0].id);
  await onFormChange(form, async ({ a, b }, current) => {
    if (a === b) {
      showError(section, "Choose two different rides.");
      table.hidden = true;
      return;
    }
    try {
      /** @type {import("../api-types").HorseProfilePairOut} */
      const pair = await get(`/api/horses/${horseId}/ride-pair`, { params: { a, b } });
      if (!current()) return;
      showError(section, null);
      table.tBodies[0].replaceChildren(...pair.indicators.map((row) => h("tr", { dataset: { key: row.key } },
        h("th", { scope: "row" }, labelText(row.label),
          // times and distances say their own units ("12 min", "about 40 m"): an "h" beside them misleads
          row.unit && !SAYS_ITS_UNIT.has(row.unit) ? h("span", { class: "unit", dataset: { unit: "" } },
            prettyUnit(row.unit)) : null),
        h("td", { class: "num", dataset: { value: row.a ?? "" } }, pairValue(row.a, row.unit)),
        h("td", { class: "num", dataset: { value: row.b ?? "" } }, pairValue(row.b, row.unit)),
        differenceCell(row))));
      table.hidden = false;
      one(view, "[data-pair-motion-link]", HTMLAnchorElement).href = `#/compare-rides/${a}/${b}`;
      one(view, "[data-pair-motion]").hidden = false;
    } catch (error) {
      if (current()) showError(section, error);
    }
  });
}

const SAYS_ITS_UNIT = new Set(["h", "km"]);

/**
 * A value of the pair table: exposure times as "2 h 05 min", distances as "about 40 m", the rest with three digits.
 * @param {number | null} value
 * @param {string} unit
 */
function pairValue(value, unit) {
  if (unit === "h" && value !== null && Number.isFinite(value)) return durationText(value);
  if (unit === "km" && value !== null && Number.isFinite(value)) return distanceText(value);
  return fmt(value);
}

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} params the horse's id
 */
export async function mountHorse(view, params) {
  loadPlotly().catch(() => {}); // parse the chart library while the API answers (a chart says if it failed)
  view.append(page("horse"));
  const horseId = params.id;
  /** @type {HorseOut} */
  let horse;
  try {
    horse = await get(`/api/horses/${horseId}`);
  } catch (error) {
    one(view, "[data-horse-name]").textContent = "Horse not found";
    showError(one(view, "[data-horse-page-error]"), error);
    for (const panel of all(view, "section.panel")) panel.hidden = true;
    return;
  }
  showProfile(view, horse);
  for (const link of all(view, "[data-horse-export]", HTMLAnchorElement)) {
    link.href = `/api/horses/${horse.id}/export?format=${link.dataset.horseExport}`;
  }
  one(view, "[data-horse-actions]").hidden = false;
  fill(one(view, "[data-share-slot]"), shareControl({ horseId: horse.id }));
  setUpProfileForm(view, horse, (updated) => showProfile(view, updated));
  await fillOptions(view);
  const trendForm = one(view, "[data-horse-trend-form]", HTMLFormElement);
  const trendGait = field(trendForm, "gait", HTMLSelectElement);
  // The trend starts in the gait this horse has most rides in.
  const chooseGait = (/** @type {GaitGroup[]} */ groups) => {
    const most = [...groups].sort((x, y) => (y.n ?? 0) - (x.n ?? 0))[0];
    if (most?.gait && !trendForm.dataset.chosen) {
      trendGait.value = most.gait;
      trendForm.dataset.chosen = "yes";
    }
  };
  await Promise.all([setUpRides(view, horseId), setUpGaits(view, horseId, chooseGait)]);
  const saddlesForm = one(view, "[data-horse-saddles-form]", HTMLFormElement);
  field(saddlesForm, "gait", HTMLSelectElement).value = trendGait.value; // the gait it has most rides in
  await Promise.all([setUpTrend(view, horseId), setUpSaddles(view, horseId), setUpPair(view, horseId)]);
}
