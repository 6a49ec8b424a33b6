// Upload a ride: a bundle zip, or the clips one by one, or a motion-capture file (C3D, TRC) analysed
// at once. Horse, rider, gait, direction, date and notes are chosen here on every path: a bundle's own
// ride.json only pre-fills them (the zip is uploaded first, its ride.json read, and the ride created
// with the form's values when the user presses the button). A ride of clips is checked before
// anything is sent (`missingBeforeUpload`): the form names every missing clip or setting.
// `#/upload?ride=ID` completes an incomplete ride: its stored clips count, only the missing are sent.

import { ApiError, del, get, getAll, patch, post, request } from "../api.js";
import { all, announce, control, field, formValues, h, messageOf, one, page, showError } from "../dom.js";
import { fillOptions } from "../options.js";
import { missingBeforeUpload, missingList } from "../ride-readiness.js";
import { navigate } from "../router.js";
import { abandonUploads, finalizeUpload, uploadResumable } from "../uploader.js";

/** @typedef {import("../uploader.js").UploadTarget} UploadTarget */
/** @typedef {import("../ride-readiness.js").Clip} Clip */
/** @typedef {Record<string, string | number>} FormValues the form's filled fields (dom.js formValues) */
/** @typedef {import("../api-types").NamedInClubOut} Named a horse, rider or saddle of a bundle: its name and the club's id */
/** @typedef {import("../api-types").BundleMetaOut} BundleMeta what GET /api/uploads/{id}/bundle-meta answers: the ride.json of an uploaded bundle */

const CAMERAS = ["left", "middle", "right"];
const CLIP_SETS = [
  { kind: "motion", label: "Motion (the ride)" },
  { kind: "static", label: "Static (horse standing, saddle marker visible)" },
  { kind: "plumb", label: "Plumb line (gravity)" },
  { kind: "calibration", label: "Calibration board" },
];
const FROM_BUNDLE = "from-bundle";

/** @param {Clip[]} stored the ride's clips on the server */
function clipCards(stored) {
  return CAMERAS.map((camera) => h("section", { class: "camera-card", "aria-label": `${camera} camera` },
    h("h3", {}, `${camera[0].toUpperCase()}${camera.slice(1)} camera`),
    ...CLIP_SETS.map((set) => {
      const id = `clip-${set.kind}-${camera}`;
      const have = stored.some((c) => c.kind === set.kind && c.camera === camera);
      return h("div", { class: "field" },
        h("label", { for: id }, set.label, have ? h("span", { class: "hint" }, " (stored)") : null,
          h("span", { class: "hint", dataset: { rigHint: "" } })),
        h("input", { id, type: "file", accept: "video/*,.mp4,.mov,.avi,.mkv", dataset: { clipKind: set.kind, camera } }));
    })));
}

/**
 * The clips chosen in the form, with the kind and camera of each.
 * @param {HTMLFormElement} form
 * @returns {(Clip & {file: File})[]}
 */
function chosenClips(form) {
  return all(form, "input[data-clip-kind]", HTMLInputElement)
    .filter((input) => input.files?.length)
    .map((input) => ({ file: /** @type {FileList} */ (input.files)[0], kind: input.dataset.clipKind ?? "",
      camera: input.dataset.camera ?? "" }));
}

/** @param {number} bytes */
function mib(bytes) {
  return `${(bytes / 1048576).toFixed(bytes < 10485760 ? 1 : 0)} MiB`;
}

const today = () => new Date().toISOString().slice(0, 10);

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} _params
 * @param {URLSearchParams} query
 */
export async function mountUpload(view, _params, query) {
  view.append(page("upload"));
  const form = one(view, "[data-upload-form]", HTMLFormElement);
  const progressBox = one(form, "[data-upload-progress]");
  const progress = one(progressBox, "progress", HTMLProgressElement);
  const status = one(form, "[data-upload-status]");
  const label = one(form, "[data-upload-label]");
  const submit = one(form, "[data-upload-submit]", HTMLButtonElement);
  const cancel = one(form, "[data-upload-cancel]");
  const readiness = one(form, "[data-readiness]");
  const prefillNote = one(form, "[data-bundle-prefill]");
  const rigSelect = field(form, "rig_id", HTMLSelectElement);
  /** @type {AbortController | null} */
  let controller = null;
  /** @type {{file: File, target: UploadTarget}[]} */
  let active = [];
  /** @type {{upload: {id: string, key: string}, file: File} | null} uploaded, read, not yet a ride */
  let stagedBundle = null;
  /** @type {unknown} why the chosen bundle could not be read */
  let bundleError = null;
  const completing = query?.get?.("ride") ? Number(query.get("ride")) : null;
  let pendingRideId = completing;
  /** @type {Clip[]} the ride's clips already on the server (completing a ride) */
  let storedClips = [];
  /** @type {import("../api-types").RigOut[]} */
  let rigs = [];
  /** @type {{rig: import("../api-types").RigOut | null, clips: Clip[]}} */
  let rigInfo = { rig: null, clips: [] };

  const source = () => one(form, "[data-upload-source]:checked", HTMLInputElement).value;
  /** The abort signal of the upload under way (set before any upload starts). */
  const signal = () => /** @type {AbortController} */ (controller).signal;

  async function loadRigs() {
    rigs = await getAll("/api/rigs");
    const select = rigSelect;
    const keep = select.value;
    select.replaceChildren(h("option", { value: "" }, rigs.length ? "choose the rig\u2026" : "no rigs yet: add one on the Rigs page"),
      ...rigs.map((rig) => h("option", { value: rig.id }, `${rig.name} (${rig.calibrated ? "calibrated" : "not calibrated"})`)));
    if (keep) select.value = keep;
  }

  // The rig's clips as last asked (a rig chosen and "Upload and analyse" pressed at once waits for them).
  /** @type {Promise<void>} */
  let rigLoaded = Promise.resolve();

  async function loadRig() {
    const id = Number(rigSelect.value) || null;
    const rig = rigs.find((r) => r.id === id) || null;
    /** @type {import("../api-types").RecordingOut[]} */
    const stored = rig ? await get(`/api/rigs/${rig.id}/clips`) : [];
    if ((Number(rigSelect.value) || null) !== id) return; // another rig was chosen meanwhile: its answer counts
    const clips = stored.map((c) => ({ kind: c.clip_kind, camera: c.camera_role }));
    rigInfo = { rig, clips };
    markRigClips();
    checkReadiness();
  }

  // Clips the chosen rig already holds need not be sent again: say so beside each file field.
  function markRigClips() {
    for (const input of all(form, "input[data-clip-kind]", HTMLInputElement)) {
      const { clipKind, camera } = input.dataset;
      const fromRig = rigInfo.clips.some((c) => c.kind === clipKind && c.camera === camera)
        || (clipKind === "calibration" && rigInfo.rig?.calibrated);
      const hint = input.closest(".field")?.querySelector("[data-rig-hint]") ?? null;
      if (hint) hint.textContent = fromRig ? " – the rig has it: only to replace it for this ride" : "";
    }
  }

  function missingNow() {
    const chosen = chosenClips(form).map(({ kind, camera }) => ({ kind, camera }));
    return missingBeforeUpload({ rideClips: [...storedClips, ...chosen], rig: rigInfo.rig, rigClips: rigInfo.clips });
  }

  function checkReadiness() {
    const missing = source() === "clips" ? missingNow() : [];
    readiness.hidden = !missing.length;
    one(form, "[data-readiness-list]").replaceChildren(missingList(missing));
    return missing;
  }

  function showSource() {
    for (const part of all(form, "[data-upload-part]")) part.hidden = part.dataset.uploadPart !== source();
    // A motion-capture file has no cameras to calibrate.
    /** @type {HTMLElement} */ (rigSelect.closest(".field")).hidden = source() === "mocap";
    checkReadiness();
  }
  for (const radio of all(form, "[data-upload-source]")) radio.addEventListener("change", showSource);

  /**
   * @param {boolean} on
   * @param {string} [text]
   */
  function setBusy(on, text = "") {
    submit.disabled = on;
    cancel.hidden = !on;
    progressBox.hidden = !on && !text;
    form.setAttribute("aria-busy", on ? "true" : "false");
    if (text) status.textContent = text;
  }

  /**
   * A progress function for `totalBytes` sent in parts: call it with each part's name and bytes sent.
   * @param {number} totalBytes
   * @returns {(name: string, bytes: number) => void}
   */
  function track(totalBytes) {
    /** @type {Map<string, number>} */
    const sent = new Map();
    progress.max = Math.max(totalBytes, 1);
    progress.value = 0;
    let lastAnnounced = -1;
    return (name, bytes) => {
      sent.set(name, bytes);
      const done = [...sent.values()].reduce((a, b) => a + b, 0);
      progress.value = done;
      const percent = Math.floor((100 * done) / Math.max(totalBytes, 1));
      status.textContent = `${percent} % (${mib(done)} of ${mib(totalBytes)})`;
      // aria-live speaks every change; announce only each tenth to keep it useful.
      if (Math.floor(percent / 10) !== lastAnnounced) {
        lastAnnounced = Math.floor(percent / 10);
        progress.setAttribute("aria-valuetext", `${percent} percent uploaded`);
      }
    };
  }

  /**
   * Choose `id` in `select`, or add a "new, from the bundle" choice named `name` and choose that.
   * @param {HTMLSelectElement} select
   * @param {Named | null | undefined} entity
   * @param {string} what
   */
  function prefillEntity(select, entity, what) {
    for (const old of select.querySelectorAll(`option[value="${FROM_BUNDLE}"]`)) old.remove();
    if (entity?.id) {
      select.value = String(entity.id);
      return null;
    }
    if (!entity?.name) return null;
    select.prepend(h("option", { value: FROM_BUNDLE }, `${entity.name} (new ${what}, from the bundle)`));
    select.value = FROM_BUNDLE;
    return `the ${what} \u201c${entity.name}\u201d is not in the club yet: keep it to add it, or choose one of yours`;
  }

  /** @param {BundleMeta} meta */
  function prefill(meta) {
    const select = (/** @type {string} */ name) => field(form, name, HTMLSelectElement);
    const notes = [prefillEntity(select("horse_id"), meta.horse, "horse"), prefillEntity(select("rider_id"), meta.rider, "rider"),
      prefillEntity(select("saddle_id"), meta.saddle, "saddle")];
    const text = (/** @type {string} */ name) => control(form, name);
    if (meta.pad && !text("pad").value) text("pad").value = meta.pad;
    if (meta.rider_weight_kg != null && Number.isFinite(meta.rider_weight_kg) && !text("rider_weight_kg").value) {
      text("rider_weight_kg").value = String(meta.rider_weight_kg);
    }
    if (meta.gait) text("gait").value = meta.gait;
    if (meta.direction) text("direction").value = meta.direction;
    if (meta.ridden_on) text("ridden_on").value = meta.ridden_on;
    if (meta.notes && !text("notes").value) text("notes").value = meta.notes;
    const extra = notes.filter(Boolean);
    prefillNote.textContent = `Filled in from the bundle's ride.json: check the ride's details above, then press \u201cUpload and analyse\u201d.${extra.length ? ` Note: ${extra.join("; ")}.` : ""}`;
    prefillNote.hidden = false;
  }

  async function stageBundle() {
    const input = field(form, "bundle");
    stagedBundle = null;
    bundleError = null;
    prefillNote.hidden = true;
    if (!input.files?.length) return;
    const file = input.files[0];
    controller = new AbortController();
    setBusy(true, "Starting\u2026");
    showError(form, null);
    try {
      /** @type {UploadTarget} */
      const target = { target: "bundle", ...(rigSelect.value ? { rig_id: Number(rigSelect.value) } : {}) };
      active = [{ file, target }];
      const progressOf = track(file.size);
      label.textContent = `Uploading ${file.name}`;
      const upload = await uploadResumable(file, target,
        { signal: signal(), finalize: false, onProgress: (b) => progressOf(file.name, b) });
      try {
        prefill(await get(`/api/uploads/${upload.id}/bundle-meta`));
      } catch (error) {
        // An unreadable bundle leaves nothing behind: its bytes go.
        window.localStorage.removeItem(upload.key);
        await del(`/api/uploads/${upload.id}`).catch(() => {});
        throw error;
      }
      stagedBundle = { upload, file };
      label.textContent = `${file.name} uploaded`;
      setBusy(false, "Uploaded; check the details, then press \u201cUpload and analyse\u201d.");
    } catch (error) {
      bundleError = error;
      setBusy(false);
      progressBox.hidden = true;
      showError(form, isAbort(error) ? "Upload cancelled." : reason(error));
    }
  }
  field(form, "bundle").addEventListener("change", stageBundle);

  /**
   * The ride's details as the form has them (a bundle's, over its ride.json).
   * @param {FormValues} values
   * @returns {Record<string, string | number | null>}
   */
  function chosenDetails(values) {
    /** @type {Record<string, string | number | null>} */
    const details = { gait: values.gait, direction: values.direction, ridden_on: values.ridden_on || null, notes: values.notes || "" };
    if (values.horse_id && values.horse_id !== FROM_BUNDLE) details.horse_id = Number(values.horse_id);
    if (values.rider_id && values.rider_id !== FROM_BUNDLE) details.rider_id = Number(values.rider_id);
    if (values.rig_id) details.rig_id = Number(values.rig_id);
    Object.assign(details, saddleDetails(values));
    return details;
  }

  // The saddle, pad and rider's weight chosen (left out when empty: the bundle's, or the rider's weight).
  /** @param {FormValues} values */
  function saddleDetails(values) {
    /** @type {{saddle_id?: number, pad?: string | number, rider_weight_kg?: number}} */
    const details = {};
    if (values.saddle_id && values.saddle_id !== FROM_BUNDLE) details.saddle_id = Number(values.saddle_id);
    if (values.pad) details.pad = values.pad;
    const weight = values.rider_weight_kg;
    if (typeof weight === "number" && Number.isFinite(weight)) details.rider_weight_kg = weight; // data-kind="float"
    return details;
  }

  /** @param {FormValues} values */
  async function uploadBundle(values) {
    if (!stagedBundle) {
      if (!field(form, "bundle").files?.length) throw new Error("Please choose the ride bundle (.zip).");
      if (bundleError) throw bundleError;
      await stageBundle();
      if (bundleError) throw bundleError;
      throw new Error("Check the details read from the bundle, then press \u201cUpload and analyse\u201d again.");
    }
    const details = chosenDetails(values);
    if (!details.ridden_on) delete details.ridden_on;
    label.textContent = `Creating the ride from ${stagedBundle.file.name}`;
    const answer = await finalizeUpload(stagedBundle.upload, details, { signal: signal() });
    stagedBundle = null;
    return "ride_id" in answer ? answer.ride_id : undefined; // a bundle's finalize answers BundleFinalisedOut
  }

  /** @param {FormValues} values */
  async function uploadClips(values) {
    await rigLoaded.catch(() => undefined); // the chosen rig's clips decide what is missing (its error is shown)
    const missing = checkReadiness();
    if (missing.length) throw new Error("Nothing was sent: the ride cannot be analysed without what is listed above.");
    if (!completing && (!values.horse_id || !values.rider_id)) throw new Error("Please choose the horse and the rider.");
    const clips = chosenClips(form);
    const fields = {
      horse_id: Number(values.horse_id), rider_id: Number(values.rider_id), gait: values.gait,
      direction: values.direction, rig_id: Number(values.rig_id), ridden_on: values.ridden_on || null,
      notes: values.notes || "", ...saddleDetails(values),
    };
    // After a failed attempt the ride exists already: send the clips to it again instead of a new one.
    /** @type {{id: number}} the ride (a RideOut when made or changed here) */
    const ride = pendingRideId ? (completing === pendingRideId ? { id: pendingRideId } : await patch(`/api/rides/${pendingRideId}`, fields))
      : await post("/api/rides", fields);
    pendingRideId = ride.id;
    const progressOf = track(clips.reduce((total, c) => total + c.file.size, 0));
    active = [];
    /** @type {import("../uploader.js").Finalized | null} */
    let last = null;
    for (const clip of clips) {
      // the clip fields' kinds and cameras are the API's (CLIP_SETS, CAMERAS)
      const target = /** @type {UploadTarget} */ ({ target: "ride_clip", ride_id: ride.id, clip_kind: clip.kind, camera: clip.camera });
      active.push({ file: clip.file, target });
      label.textContent = `Uploading the ${clip.kind} clip of the ${clip.camera} camera`;
      last = await uploadResumable(clip.file, target, {
        signal: signal(), onProgress: (b) => progressOf(`${clip.kind}/${clip.camera}`, b) });
    }
    if (last && last.job_id == null) {
      // Stored, but the server found something still missing: say so instead of "queued".
      /** @type {import("../api-types").ReadinessOut} */
      const answer = await get(`/api/rides/${ride.id}/readiness`);
      if (!answer.ready) {
        readiness.hidden = false;
        one(form, "[data-readiness-list]").replaceChildren(missingList(answer.missing));
        throw new Error(`The clips are stored with ride ${ride.id}, but it cannot be analysed yet (see above).`);
      }
    }
    return ride.id;
  }

  /** @param {FormValues} values */
  async function uploadMocap(values) {
    const input = field(form, "mocap");
    if (!input.files?.length) throw new Error("Please choose the C3D or TRC file.");
    const labels = String(values.markers || "").split(",").map((l) => l.trim()).filter(Boolean);
    if (labels.length !== 3) throw new Error("Please name three marker labels for M1, M2 and M3, separated by commas.");
    const file = input.files[0];
    label.textContent = `Uploading and analysing ${file.name}`;
    progress.removeAttribute("value");  // indeterminate: the file goes in one request, analysed on arrival
    /** @type {import("../api-types").MocapRideOut | null} */
    const answer = await request("POST", "/api/mocap", {
      body: file, signal: signal(), headers: { "Content-Type": "application/octet-stream" },
      params: {
        horse_id: values.horse_id, rider_id: values.rider_id, gait: values.gait, direction: values.direction,
        ridden_on: values.ridden_on, markers: labels.join(","), point: values.point, up: values.up,
        strides: values.strides, filename: file.name, ...saddleDetails(values),
      },
    });
    return answer?.ride?.id;
  }

  /** @param {unknown} error */
  function reason(error) {
    // The server's reason verbatim (e.g. 422 "... is not a zip file"), with the status for 4xx/5xx.
    return error instanceof ApiError && error.status ? `${error.message} (HTTP ${error.status})` : messageOf(error);
  }

  /** @param {unknown} error whether it is the Cancel button's (an aborted fetch) */
  function isAbort(error) {
    return error instanceof Error && error.name === "AbortError";
  }

  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    showError(form, null);
    const values = formValues(form);
    controller = new AbortController();
    setBusy(true, "Starting\u2026");
    try {
      /** @type {Record<string, (values: FormValues) => Promise<number | undefined>>} */
      const ways = { bundle: uploadBundle, clips: uploadClips, mocap: uploadMocap };
      const rideId = await ways[source()](values);
      pendingRideId = null;
      setBusy(false, "Upload complete.");
      announce(source() === "mocap" ? "Upload complete; the ride is analysed." : "Upload complete; the analysis has been queued.");
      navigate(rideId ? `/rides/${rideId}` : "/jobs");
    } catch (error) {
      setBusy(false);
      progressBox.hidden = true;
      showError(form, isAbort(error) ? "Upload cancelled." : reason(error));
      if (error instanceof ApiError && Number.isInteger(error.body?.ride_id)) await sameClipsAgain(error.body.ride_id);
    }
  });

  // The same clips again (409 naming the ride they already are): the empty ride just made for them goes,
  // and the error links to the existing one.
  /** @param {number} existing the ride the clips are already */
  async function sameClipsAgain(existing) {
    if (pendingRideId && pendingRideId !== completing && pendingRideId !== existing) {
      try {
        await del(`/api/rides/${pendingRideId}`);
        pendingRideId = null;
      } catch {
        // kept: the member may not delete it (the error above still names the existing ride)
      }
    }
    one(form, "[data-form-error]").append(" ", h("a", { href: `#/rides/${existing}`, "data-existing-ride": existing },
      `Open ride ${existing}`));
  }

  cancel.addEventListener("click", async () => {
    controller?.abort();
    await Promise.all(active.map(({ file, target }) => abandonUploads(file, target)));
  });
  rigSelect.addEventListener("change", () => {
    rigLoaded = loadRig();
    rigLoaded.catch((error) => showError(form, error));
  });
  form.addEventListener("change", (event) => {
    if (/** @type {HTMLElement} */ (event.target).dataset?.clipKind) checkReadiness();
  });

  try {
    control(form, "ridden_on").value = today();
    await Promise.all([fillOptions(form), loadRigs()]);
    if (completing) {
      /** @type {Promise<import("../api-types").RideDetail>} */
      const asked = get(`/api/rides/${completing}`);
      /** @type {Promise<import("../api-types").RecordingOut[]>} */
      const askedClips = get(`/api/rides/${completing}/clips`);
      const [ride, clips] = await Promise.all([asked, askedClips]);
      storedClips = clips.map((c) => ({ kind: c.clip_kind, camera: c.camera_role }));
      for (const name of /** @type {const} */ (["horse_id", "rider_id", "gait", "direction", "ridden_on", "rig_id"])) {
        if (ride[name] != null) control(form, name).value = String(ride[name]);
      }
      one(form, '[data-upload-source][value="clips"]', HTMLInputElement).checked = true;
      // The ride exists: only its missing clips are sent (its details are changed on the ride page).
      for (const name of ["horse_id", "rider_id", "gait", "direction", "ridden_on", "rig_id", "notes"]) control(form, name).disabled = true;
      for (const radio of all(form, "[data-upload-source]", HTMLInputElement)) radio.disabled = radio.value !== "clips";
      one(view, "h1").textContent = `Complete ride ${completing}`;
    }
    const rigAsked = query?.get?.("rig");
    if (!completing && rigAsked) rigSelect.value = rigAsked;  // from a rig page
    one(form, "[data-clip-cards]").append(...clipCards(storedClips));
    showSource();
    rigLoaded = loadRig();
    await rigLoaded;
  } catch (error) {
    showError(form, error);
  }
  return () => controller?.abort();
}
