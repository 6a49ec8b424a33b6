// What a ride still needs before it can be analysed: the server's answer for a stored ride
// (`mountReadiness`, for the ride page) and the same check on the upload form before anything is sent
// (`missingBeforeUpload`). The sentences follow backend/saddlescope/services/rides/readiness.py.

import { get } from "./api.js";
import { h } from "./dom.js";

/** @typedef {{kind: string, camera: string}} Clip a clip chosen or stored: its kind and camera */

export const CAMERAS = ["left", "middle", "right"];
/** @type {Record<string, [string, string]>} each clip kind's name and what it shows */
const CLIP_WORDS = {
  calibration: ["calibration", "the board moved through the view"],
  plumb: ["plumb-line", "the plumb line hanging still"],
  static: ["static", "horse standing still, saddle marker visible"],
  motion: ["motion", "the ride"],
};
/** @type {(kind: string, plural?: boolean) => string} */
const clipsOf = (kind, plural = false) => `${CLIP_WORDS[kind][0]} clip${plural ? "s" : ""} (${CLIP_WORDS[kind][1]})`;

/** @type {(names: string[]) => string} */
const and = (names) => (names.length === 1 ? names[0] : `${names.slice(0, -1).join(", ")} and ${names.at(-1)}`);
/** @type {(have: Set<string>) => string[]} */
const lacking = (have) => CAMERAS.filter((c) => !have.has(c));

/**
 * @param {Clip[]} clips
 * @param {string} kind
 */
function camerasOf(clips, kind) {
  return new Set(clips.filter((c) => c.kind === kind).map((c) => c.camera));
}

/**
 * @param {string} kind
 * @param {Set<string>} own the ride's cameras with such a clip
 * @param {Set<string>} shared the rig's
 * @param {string} where
 * @returns {string[]}
 */
function clipSentences(kind, own, shared, where) {
  if (!lacking(own).length || !lacking(shared).length) return [];
  const have = own.size ? own : shared;
  if (!have.size) return [`The ${clipsOf(kind, true)} of the left, middle and right cameras are missing; upload them ${where}.`];
  const gap = lacking(have);
  const sorted = [...have].sort();
  const many = gap.length > 1;
  return [`The ${clipsOf(kind, many)} of the ${and(gap)} camera${many ? "s" : ""} ${many ? "are" : "is"} missing (there ${sorted.length === 1 ? "is" : "are"} only the ${and(sorted)} one${sorted.length > 1 ? "s" : ""}); upload ${many ? "them" : "it"} ${where}.`];
}

/**
 * What a ride of clips still lacks, before anything is sent.
 * `rideClips`: [{kind, camera}] chosen in the form (and already stored); `rig`: the chosen rig
 * ({name, board, calibrated}) or null; `rigClips`: the rig's stored clips as [{kind, camera}].
 * @param {{rideClips: Clip[], rig: {name: string, board?: unknown, calibrated: boolean} | null, rigClips?: Clip[]}} what
 * @returns {string[]}
 */
export function missingBeforeUpload({ rideClips, rig, rigClips = [] }) {
  /** @type {string[]} */
  const missing = [];
  if (!rig) {
    missing.push("No camera rig is chosen: choose the rig these clips were filmed with (its calibration board is needed; create one on the Rigs page).");
  } else {
    if (!rig.board) missing.push(`The rig \u201c${rig.name}\u201d has no calibration board described: set its board on the rig page.`);
    const own = camerasOf(rideClips, "calibration");
    const shared = camerasOf(rigClips, "calibration");
    if (!rig.calibrated && lacking(own).length && lacking(shared).length) {
      const have = own.size ? own : shared;
      if (have.size) {
        const [whose, where] = own.size ? ["the ride's", "with the ride"] : ["its", "on the rig page"];
        missing.push(`The rig \u201c${rig.name}\u201d is not calibrated: ${whose} calibration clips come from only ${have.size} camera${have.size > 1 ? "s" : ""} (${and([...have].sort())}); upload the ${and(lacking(have))} camera's calibration clip ${where}.`);
      } else {
        missing.push(`The rig \u201c${rig.name}\u201d is not calibrated and has no calibration clips: upload the calibration clips of its three cameras on the rig page.`);
      }
    }
  }
  const where = rig ? "with the ride, or on the rig page" : "with the ride on the upload page";
  missing.push(...clipSentences("static", camerasOf(rideClips, "static"), camerasOf(rigClips, "static"), where));
  missing.push(...clipSentences("motion", camerasOf(rideClips, "motion"), new Set(), "with the ride on the upload page"));
  const plumbOwn = camerasOf(rideClips, "plumb");
  const plumbShared = camerasOf(rigClips, "plumb");
  if ((plumbOwn.size || plumbShared.size) && lacking(plumbOwn).length && lacking(plumbShared).length) {
    missing.push(...clipSentences("plumb", plumbOwn, plumbShared, where));
  }
  return missing;
}

/**
 * The list of what is missing, as shown on the upload form and the ride page.
 * @param {string[]} missing
 */
export function missingList(missing) {
  return h("ul", { class: "readiness-missing" }, ...missing.map((sentence) => h("li", {}, sentence)));
}

/**
 * On the ride page of an incomplete ride: what it still needs, with a link to complete it on the
 * upload page. Renders nothing for a ride that can run. Resolves to the server's answer.
 * @param {HTMLElement} container
 * @param {number} rideId
 * @returns {Promise<import("./api-types").ReadinessOut>}
 */
export async function mountReadiness(container, rideId) {
  /** @type {import("./api-types").ReadinessOut} */
  const answer = await get(`/api/rides/${rideId}/readiness`);
  if (answer.ready) {
    container.replaceChildren();
    return answer;
  }
  container.replaceChildren(h("section", { class: "readiness caveat", "aria-label": "What this ride still needs" },
    h("p", {}, h("strong", {}, "This ride cannot be analysed yet."), " What is missing:"),
    missingList(answer.missing),
    h("p", {}, h("a", { href: `#/upload?ride=${rideId}` }, "Add the missing clips on the upload page"),
      " (or delete the ride from the rides list).")));
  return answer;
}
