// <select data-options="horses|riders|saddles|saddle-types|rigs|gaits|indicators|ranked-indicators">: filled from the API.
// data-optional="text" adds a first, empty choice with that text.

import { getAll } from "./api.js";
import { h } from "./dom.js";
import { COMFORT_INDICATORS, GAITS, gaitLabel, indicatorInfoOf, indicatorKeys, labelText, prettyUnit } from "./format.js";
import { glossaryEntries } from "./glossary.js";

/**
 * One choice of a picker; `group` names its <optgroup>.
 * @typedef {object} Choice
 * @property {string | number} value
 * @property {string} text
 * @property {string | null} [title]
 * @property {string} [group]
 */

/** @typedef {import("./format.js").IndicatorInfo} IndicatorInfo */

/** @type {<T extends {name: string}>(items: T[]) => T[]} */
const byName = (items) => [...items].sort((a, b) => a.name.localeCompare(b.name));

/** @type {Record<string, () => Promise<Choice[]>>} */
const SOURCES = {
  horses: async () => byName(/** @type {import("./api-types").HorseOut[]} */ (await getAll("/api/horses")))
    .map((horse) => ({ value: horse.id, text: horse.name })),
  riders: async () => byName(/** @type {import("./api-types").RiderOut[]} */ (await getAll("/api/riders")))
    .map((rider) => ({ value: rider.id, text: rider.name })),
  saddles: async () => byName(/** @type {import("./api-types").SaddleOut[]} */ (await getAll("/api/saddles")))
    .map((saddle) => ({ value: saddle.id, text: saddle.name })),
  "saddle-types": async () => glossaryEntries("saddle_type").map((e) => ({ value: e.code, text: e.label })),
  rigs: async () => (/** @type {import("./api-types").RigOut[]} */ (await getAll("/api/rigs")))
    .map((rig) => ({ value: rig.id, text: `${rig.name}${rig.calibrated ? " (calibrated)" : ""}` })),
  gaits: async () => GAITS.map((gait) => ({ value: gait, text: gaitLabel(gait) })),
  indicators: async () => indicatorChoices(() => true),
  "ranked-indicators": async () => indicatorChoices((info) => info.better === "lower" || info.better === "higher"),
};

/**
 * @param {(info: IndicatorInfo) => boolean} keep
 * @returns {Choice[]}
 */
function indicatorChoices(keep) {
  // The thesis's eight comfort indicators first (the headline numbers), then the glossary's expert
  // indicators (MTVV, the W_d axes, worst-axis times, ...) in their own group "Expert detail".
  const keys = [...COMFORT_INDICATORS, ...indicatorKeys().filter((k) => !COMFORT_INDICATORS.includes(k))];
  return keys.filter((key) => keep(indicatorInfoOf(key))).map((key) => {
    const info = indicatorInfoOf(key);
    const unit = info.unit ? ` (${prettyUnit(info.unit)})` : "";
    const expert = info.expert ?? !COMFORT_INDICATORS.includes(key);
    return { value: key, text: `${labelText(info.label)}${unit}`, title: info.short || null,
      group: expert ? "Expert detail" : "Headline numbers" };
  });
}

/**
 * Options, in <optgroup>s where the choices name their group.
 * @param {Choice[]} choices
 * @returns {Element[]}
 */
function optionElements(choices) {
  const option = (/** @type {Choice} */ c) => h("option", { value: c.value, title: c.title ?? null }, c.text);
  if (!choices.some((c) => c.group)) return choices.map(option);
  /** @type {Map<string | undefined, Element[]>} */
  const groups = new Map();
  for (const c of choices) {
    if (!groups.has(c.group)) groups.set(c.group, []);
    groups.get(c.group)?.push(option(c));
  }
  return [...groups].map(([label, options]) => h("optgroup", { label }, ...options));
}

/**
 * Fill every data-options select under `root`; returns when all are filled.
 * @param {ParentNode} root
 */
export async function fillOptions(root) {
  const selects = [...root.querySelectorAll("select[data-options]")].filter((el) => el instanceof HTMLSelectElement);
  /** @type {Map<string, Promise<Choice[]>>} */
  const cache = new Map();
  await Promise.all(selects.map(async (select) => {
    const source = select.dataset.options ?? "";
    if (!cache.has(source)) cache.set(source, SOURCES[source]());
    const choices = (await cache.get(source)) ?? [];
    const keep = select.value;
    const options = optionElements(choices);
    if (select.dataset.optional) options.unshift(h("option", { value: "" }, select.dataset.optional));
    if (!options.length) options.push(h("option", { value: "", disabled: true }, `no ${source} yet`));
    select.replaceChildren(...options);
    if (keep && choices.some((c) => String(c.value) === keep)) select.value = keep;
  }));
}
