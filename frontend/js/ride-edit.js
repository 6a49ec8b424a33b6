// A ride's details after upload: horse, rider, gait, direction, date, saddle, pad, rider's weight and
// notes, saved with PATCH; when
// a change alters what the analysis computes (gait, direction: the pipeline reads them) the result
// shown is said to be from the old details and "Re-analyse now" is offered. Deleting the ride asks
// first, naming it. The ride page calls mountRideEdit in its <section data-ride-edit-slot>.

import { del, patch, post } from "./api.js";
import { announce, busy, control, h, maybeControl, one, showError } from "./dom.js";
import { gaitLabel } from "./format.js";
import { fillOptions } from "./options.js";
import { can } from "./session.js";

/** @typedef {import("./api-types").RideOut} RideOut */
/** @typedef {import("./api-types").JobOut} JobOut */

// The details the analysis reads (saddlescope.services.rides.registration.RESULT_SETTINGS), in words.
/** @type {Record<string, string>} */
const SETTING_WORDS = { gait: "gait", direction: "direction" };
/** @type {(keyof RideOut & keyof import("./api-types").RideUpdate)[]} */
const FIELDS = ["horse_id", "rider_id", "gait", "direction", "ridden_on", "saddle_id", "pad", "rider_weight_kg", "notes"];
// Fields a cleared box sends as null (not recorded), and those sent as numbers.
const CLEARABLE = new Set(["ridden_on", "saddle_id", "pad", "rider_weight_kg"]);
const INTEGERS = new Set(["horse_id", "rider_id", "saddle_id"]);

/** @param {string} name */
function part(name) {
  const template = /** @type {HTMLTemplateElement | null} */ (document.getElementById(`part-${name}`));
  if (!template) throw new Error(`no template part-${name}`);
  return template.content.cloneNode(true);
}

/** @param {string[]} names */
function words(names) {
  const list = names.map((name) => SETTING_WORDS[name] ?? name);
  return list.length > 1 ? `${list.slice(0, -1).join(", ")} and ${list.at(-1)}` : list[0];
}

/**
 * A short name of the ride ("ride #12 of Bravo (canter, 2026-03-01)").
 * @param {RideOut} ride
 */
function titleOf(ride) {
  const date = ride.ridden_on ?? "no date";
  return `ride #${ride.id} of ${ride.horse_name} (${gaitLabel(ride.gait)}, ${date})`;
}

/**
 * Ask in a dialog whether to delete `ride` (named by `title`), then delete it.
 * Resolves true when deleted, false when the user kept it; rejects with the server's reason.
 * @param {{id: number}} ride
 * @param {string} title
 * @returns {Promise<boolean>}
 */
export async function deleteRideWithConfirmation(ride, title) {
  const confirmButton = h("button", { type: "submit", value: "delete", class: "danger", "data-ride-delete-confirm": true },
    "Delete ride");
  const dialog = h("dialog", { class: "confirm", "aria-labelledby": "ride-delete-title", "data-ride-delete-dialog": true },
    h("form", { method: "dialog" },
      h("h2", { id: "ride-delete-title" }, `Delete ${title}?`),
      h("p", {}, "Its clips, result files, jobs and grades are deleted with it. This cannot be undone."),
      h("div", { class: "buttons" },
        h("button", { type: "submit", value: "cancel", "data-ride-delete-cancel": true, autofocus: true }, "Keep the ride"),
        confirmButton)));
  document.body.append(dialog);
  const answer = await new Promise((resolve) => {
    dialog.addEventListener("close", () => resolve(dialog.returnValue), { once: true });
    dialog.showModal();
  });
  dialog.remove();
  if (answer !== "delete") return false;
  await del(`/api/rides/${ride.id}`);
  announce(`${title[0].toUpperCase()}${title.slice(1)} deleted.`);
  return true;
}

/**
 * Fill `container` with the edit form of `ride` (a RideOut or RideDetail).
 * `onSaved(ride)` gets the saved ride, `onDeleted(ride)` is called after a deletion,
 * `onReanalyse(job)` after a re-analysis was queued. Returns a cleanup function.
 * @template {RideOut} R
 * @param {HTMLElement} container
 * @param {R} ride
 * @param {{onSaved?: (ride: R) => unknown, onDeleted?: (ride: R) => unknown, onReanalyse?: (job: JobOut) => unknown}} [actions]
 * @returns {Promise<() => void>}
 */
export async function mountRideEdit(container, ride, { onSaved, onDeleted, onReanalyse } = {}) {
  container.replaceChildren(part("ride-edit"));
  const form = one(container, "[data-ride-edit-form]", HTMLFormElement);
  const outdated = one(container, "[data-ride-edit-outdated]");
  const outdatedText = one(container, "[data-ride-edit-outdated-text]");
  const reanalyse = one(container, "[data-ride-edit-reanalyse]");
  const remove = one(container, "[data-ride-edit-delete]");
  const heading = one(container, "[data-ride-edit-title]");
  let current = ride;

  function showOutdated() {
    const changed = current.result_outdated_by ?? [];
    const hasResult = current.status === "analysed" || Boolean(current.indicators);
    outdated.hidden = !(changed.length && hasResult);
    if (!outdated.hidden) {
      outdatedText.textContent = `The result shown was computed with the old ${words(changed)}: it stays `
        + "until the ride is analysed again with the new details.";
    }
    reanalyse.hidden = !can("ride.analyse", current.created_by);
  }

  function fill() {
    for (const name of FIELDS) {
      const el = maybeControl(form, name);
      if (el) el.value = String(current[name] ?? "");
    }
    heading.textContent = `Details of ${titleOf(current)}`;
    remove.hidden = !can("ride.delete", current.created_by);
    showOutdated();
  }

  try {
    await fillOptions(form);
  } catch (error) {
    showError(form, error);
  }
  fill();

  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    /** @type {Record<string, string | number | null>} the RideUpdate */
    const values = {};
    for (const name of FIELDS) {
      const el = control(form, name);
      const raw = el.value.trim();
      const before = current[name] ?? "";
      if (raw === String(before)) continue;
      if (!raw && CLEARABLE.has(name)) values[name] = null; // cleared: not recorded
      else if (INTEGERS.has(name)) values[name] = Number.parseInt(raw, 10);
      else if (name === "rider_weight_kg") values[name] = Number.parseFloat(raw);
      else values[name] = raw;
    }
    if (!Object.keys(values).length) {
      announce("Nothing changed.");
      return;
    }
    try {
      /** @type {RideOut} */
      const saved = await busy(form, () => patch(`/api/rides/${current.id}`, values));
      current = { ...current, ...saved };
      showError(form, null);
      fill();
      announce(`Ride #${current.id} saved.`);
      onSaved?.(current);
    } catch (error) {
      showError(form, error);
    }
  });

  reanalyse.addEventListener("click", async () => {
    try {
      /** @type {JobOut} */
      const job = await post(`/api/rides/${current.id}/analyze`);
      outdatedText.textContent = `Re-analysis queued (job #${job.id}); the result shown is from the old details `
        + "until it is done.";
      reanalyse.hidden = true;
      announce(`Re-analysis of ride #${current.id} queued.`);
      onReanalyse?.(job);
    } catch (error) {
      showError(form, error);
    }
  });

  remove.addEventListener("click", async () => {
    try {
      if (await deleteRideWithConfirmation(current, titleOf(current))) onDeleted?.(current);
    } catch (error) {
      showError(form, error);
    }
  });
  return () => container.replaceChildren();
}
