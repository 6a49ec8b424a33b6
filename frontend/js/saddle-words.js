// Saddles in words: their types as a fitter names them (the glossary's saddle_type entries), and a mean
// with its 95 % interval.

import { fmt, rangeText } from "./format.js";
import { glossaryLabel } from "./glossary.js";

/** @param {string | null | undefined} type */
export function saddleTypeText(type) {
  return type ? glossaryLabel("saddle_type", type) : "\u2013";
}

/**
 * "0.812 (0.701–0.923)": a mean and its 95 % interval; a single ride has no interval ("0.812, one ride").
 * @param {{mean?: number | null, low?: number | null, high?: number | null} | null | undefined} stats
 *   a MeanWithInterval of the API
 */
export function meanIntervalText(stats) {
  if (!stats || !Number.isFinite(stats.mean)) return "\u2013";
  if (!Number.isFinite(stats.low) || !Number.isFinite(stats.high)) return `${fmt(stats.mean)} (one ride: no interval)`;
  // The saddle's indicators (r.m.s., VDV) are never negative: a t interval of few rides may reach below 0.
  return `${fmt(stats.mean)} (${rangeText(Math.max(0, /** @type {number} */ (stats.low)), stats.high)})`; // finite: above
}
