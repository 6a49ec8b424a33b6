// Upload a ride: a bundle zip, or the clips one by one, or a motion-capture file (C3D, TRC) analysed
// at once. Horse, rider, gait, direction, date and notes are chosen here on every path: a bundle's own
// ride.json only pre-fills them (the zip is uploaded first, its ride.json read, and the ride created
// with the form's values when the user presses the button). A ride of clips is checked before
// anything is sent (`missingBeforeUpload`): the form names every missing clip or setting.
// `#/upload?ride=ID` completes an incomplete ride: its stored clips count, only the missing are sent.

import { ApiError, del, get, getAll, patch, post, request } from "../api.js";
import { announce, formValues, h, page, showError } from "../dom.js";
import { fillOptions } from "../options.js";
import { missingBeforeUpload, missingList } from "../ride-readiness.js";
import { navigate } from "../router.js";
import { abandonUploads, finalizeUpload, uploadResumable } from "../uploader.js";

const CAMERAS = ["left", "middle", "right"];
const CLIP_SETS = [
  { kind: "motion", label: "Motion (the ride)" },
  { kind: "static", label: "Static (horse standing, saddle marker visible)" },
  { kind: "plumb", label: "Plumb line (gravity)" },
  { kind: "calibration", label: "Calibration board" },
];
const FROM_BUNDLE = "from-bundle";

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

function chosenClips(form) {
  return [...form.querySelectorAll("input[data-clip-kind]")]
    .filter((input) => input.files.length)
    .map((input) => ({ file: input.files[0], kind: input.dataset.clipKind, camera: input.dataset.camera }));
}

function mib(bytes) {
  return `${(bytes / 1048576).toFixed(bytes < 10485760 ? 1 : 0)} MiB`;
}

const today = () => new Date().toISOString().slice(0, 10);

export async function mountUpload(view, _params, query) {
  view.append(page("upload"));
  const form = view.querySelector("[data-upload-form]");
  const progressBox = form.querySelector("[data-upload-progress]");
  const progress = progressBox.querySelector("progress");
  const status = form.querySelector("[data-upload-status]");
  const label = form.querySelector("[data-upload-label]");
  const submit = form.querySelector("[data-upload-submit]");
  const cancel = form.querySelector("[data-upload-cancel]");
  const readiness = form.querySelector("[data-readiness]");
  const prefillNote = form.querySelector("[data-bundle-prefill]");
  let controller = null;
  let active = [];
  let stagedBundle = null; // {upload: {id, key}, file}: uploaded, read, not yet a ride
  let bundleError = null; // why the chosen bundle could not be read
  const completing = query?.get?.("ride") ? Number(query.get("ride")) : null;
  let pendingRideId = completing;
  let storedClips = []; // the ride's clips already on the server (completing a ride)
  let rigs = [];
  let rigInfo = { rig: null, clips: [] };

  const source = () => form.querySelector("[data-upload-source]:checked").value;

  async function loadRigs() {
    rigs = await getAll("/api/rigs");
    const select = form.elements.rig_id;
    const keep = select.value;
    select.replaceChildren(h("option", { value: "" }, rigs.length ? "choose the rig\u2026" : "no rigs yet: add one on the Rigs page"),
      ...rigs.map((rig) => h("option", { value: rig.id }, `${rig.name} (${rig.calibrated ? "calibrated" : "not calibrated"})`)));
    if (keep) select.value = keep;
  }

  async function loadRig() {
    const id = Number(form.elements.rig_id.value) || null;
    const rig = rigs.find((r) => r.id === id) || null;
    const clips = rig ? (await get(`/api/rigs/${rig.id}/clips`)).map((c) => ({ kind: c.clip_kind, camera: c.camera_role })) : [];
    rigInfo = { rig, clips };
    markRigClips();
    checkReadiness();
  }

  // Clips the chosen rig already holds need not be sent again: say so beside each file field.
  function markRigClips() {
    for (const input of form.querySelectorAll("input[data-clip-kind]")) {
      const { clipKind, camera } = input.dataset;
      const fromRig = rigInfo.clips.some((c) => c.kind === clipKind && c.camera === camera)
        || (clipKind === "calibration" && rigInfo.rig?.calibrated);
      const hint = input.closest(".field")?.querySelector("[data-rig-hint]");
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
    form.querySelector("[data-readiness-list]").replaceChildren(missingList(missing));
    return missing;
  }

  function showSource() {
    for (const part of form.querySelectorAll("[data-upload-part]")) part.hidden = part.dataset.uploadPart !== source();
    // A motion-capture file has no cameras to calibrate.
    form.elements.rig_id.closest(".field").hidden = source() === "mocap";
    checkReadiness();
  }
  for (const radio of form.querySelectorAll("[data-upload-source]")) radio.addEventListener("change", showSource);

  function setBusy(on, text = "") {
    submit.disabled = on;
    cancel.hidden = !on;
    progressBox.hidden = !on && !text;
    form.setAttribute("aria-busy", on ? "true" : "false");
    if (text) status.textContent = text;
  }

  function track(totalBytes) {
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

  /** Choose `id` in `select`, or add a "new, from the bundle" choice named `name` and choose that. */
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

  function prefill(meta) {
    const notes = [prefillEntity(form.elements.horse_id, meta.horse, "horse"), prefillEntity(form.elements.rider_id, meta.rider, "rider"),
      prefillEntity(form.elements.saddle_id, meta.saddle, "saddle")];
    if (meta.pad && !form.elements.pad.value) form.elements.pad.value = meta.pad;
    if (Number.isFinite(meta.rider_weight_kg) && !form.elements.rider_weight_kg.value) form.elements.rider_weight_kg.value = meta.rider_weight_kg;
    if (meta.gait) form.elements.gait.value = meta.gait;
    if (meta.direction) form.elements.direction.value = meta.direction;
    if (meta.ridden_on) form.elements.ridden_on.value = meta.ridden_on;
    if (meta.notes && !form.elements.notes.value) form.elements.notes.value = meta.notes;
    const extra = notes.filter(Boolean);
    prefillNote.textContent = `Filled in from the bundle's ride.json: check the ride's details above, then press \u201cUpload and analyse\u201d.${extra.length ? ` Note: ${extra.join("; ")}.` : ""}`;
    prefillNote.hidden = false;
  }

  async function stageBundle() {
    const input = form.elements.bundle;
    stagedBundle = null;
    bundleError = null;
    prefillNote.hidden = true;
    if (!input.files.length) return;
    const file = input.files[0];
    controller = new AbortController();
    setBusy(true, "Starting\u2026");
    showError(form, null);
    try {
      const target = { target: "bundle", ...(form.elements.rig_id.value ? { rig_id: Number(form.elements.rig_id.value) } : {}) };
      active = [{ file, target }];
      const progressOf = track(file.size);
      label.textContent = `Uploading ${file.name}`;
      const upload = await uploadResumable(file, target, { signal: controller.signal, finalize: false,
        onProgress: (b) => progressOf(file.name, b) });
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
      showError(form, error.name === "AbortError" ? "Upload cancelled." : reason(error));
    }
  }
  form.elements.bundle.addEventListener("change", stageBundle);

  function chosenDetails(values) {
    const details = { gait: values.gait, direction: values.direction, ridden_on: values.ridden_on || null, notes: values.notes || "" };
    if (values.horse_id && values.horse_id !== FROM_BUNDLE) details.horse_id = Number(values.horse_id);
    if (values.rider_id && values.rider_id !== FROM_BUNDLE) details.rider_id = Number(values.rider_id);
    if (values.rig_id) details.rig_id = Number(values.rig_id);
    Object.assign(details, saddleDetails(values));
    return details;
  }

  // The saddle, pad and rider's weight chosen (left out when empty: the bundle's, or the rider's weight).
  function saddleDetails(values) {
    const details = {};
    if (values.saddle_id && values.saddle_id !== FROM_BUNDLE) details.saddle_id = Number(values.saddle_id);
    if (values.pad) details.pad = values.pad;
    if (Number.isFinite(values.rider_weight_kg)) details.rider_weight_kg = values.rider_weight_kg;
    return details;
  }

  async function uploadBundle(values) {
    if (!stagedBundle) {
      if (!form.elements.bundle.files.length) throw new Error("Please choose the ride bundle (.zip).");
      if (bundleError) throw bundleError;
      await stageBundle();
      if (bundleError) throw bundleError;
      throw new Error("Check the details read from the bundle, then press \u201cUpload and analyse\u201d again.");
    }
    const details = chosenDetails(values);
    if (!details.ridden_on) delete details.ridden_on;
    label.textContent = `Creating the ride from ${stagedBundle.file.name}`;
    const answer = await finalizeUpload(stagedBundle.upload, details, { signal: controller.signal });
    stagedBundle = null;
    return answer.ride_id; // finalize answers {ride_id, job_id} for a bundle
  }

  async function uploadClips(values) {
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
    const ride = pendingRideId ? (completing === pendingRideId ? { id: pendingRideId } : await patch(`/api/rides/${pendingRideId}`, fields))
      : await post("/api/rides", fields);
    pendingRideId = ride.id;
    const progressOf = track(clips.reduce((total, c) => total + c.file.size, 0));
    active = [];
    let last = null;
    for (const clip of clips) {
      const target = { target: "ride_clip", ride_id: ride.id, clip_kind: clip.kind, camera: clip.camera };
      active.push({ file: clip.file, target });
      label.textContent = `Uploading the ${clip.kind} clip of the ${clip.camera} camera`;
      last = await uploadResumable(clip.file, target, {
        signal: controller.signal, onProgress: (b) => progressOf(`${clip.kind}/${clip.camera}`, b) });
    }
    if (last && last.job_id == null) {
      // Stored, but the server found something still missing: say so instead of "queued".
      const answer = await get(`/api/rides/${ride.id}/readiness`);
      if (!answer.ready) {
        readiness.hidden = false;
        form.querySelector("[data-readiness-list]").replaceChildren(missingList(answer.missing));
        throw new Error(`The clips are stored with ride ${ride.id}, but it cannot be analysed yet (see above).`);
      }
    }
    return ride.id;
  }

  async function uploadMocap(values) {
    const input = form.elements.mocap;
    if (!input.files.length) throw new Error("Please choose the C3D or TRC file.");
    const labels = (values.markers || "").split(",").map((l) => l.trim()).filter(Boolean);
    if (labels.length !== 3) throw new Error("Please name three marker labels for M1, M2 and M3, separated by commas.");
    const file = input.files[0];
    label.textContent = `Uploading and analysing ${file.name}`;
    progress.removeAttribute("value");  // indeterminate: the file goes in one request, analysed on arrival
    const answer = await request("POST", "/api/mocap", {
      body: file, signal: controller.signal, headers: { "Content-Type": "application/octet-stream" },
      params: {
        horse_id: values.horse_id, rider_id: values.rider_id, gait: values.gait, direction: values.direction,
        ridden_on: values.ridden_on, markers: labels.join(","), point: values.point, up: values.up,
        strides: values.strides, filename: file.name, ...saddleDetails(values),
      },
    });
    return answer?.ride?.id;
  }

  function reason(error) {
    // The server's reason verbatim (e.g. 422 "... is not a zip file"), with the status for 4xx/5xx.
    return error instanceof ApiError && error.status ? `${error.message} (HTTP ${error.status})` : error.message;
  }

  form.addEventListener("submit", async (event) => {
    event.preventDefault();
    showError(form, null);
    const values = formValues(form);
    controller = new AbortController();
    setBusy(true, "Starting\u2026");
    try {
      const upload = { bundle: uploadBundle, clips: uploadClips, mocap: uploadMocap }[source()];
      const rideId = await upload(values);
      pendingRideId = null;
      setBusy(false, "Upload complete.");
      announce(source() === "mocap" ? "Upload complete; the ride is analysed." : "Upload complete; the analysis has been queued.");
      navigate(rideId ? `/rides/${rideId}` : "/jobs");
    } catch (error) {
      setBusy(false);
      progressBox.hidden = true;
      showError(form, error.name === "AbortError" ? "Upload cancelled." : reason(error));
      if (error instanceof ApiError && Number.isInteger(error.body?.ride_id)) await sameClipsAgain(error.body.ride_id);
    }
  });

  // The same clips again (409 naming the ride they already are): the empty ride just made for them goes,
  // and the error links to the existing one.
  async function sameClipsAgain(existing) {
    if (pendingRideId && pendingRideId !== completing && pendingRideId !== existing) {
      try {
        await del(`/api/rides/${pendingRideId}`);
        pendingRideId = null;
      } catch {
        // kept: the member may not delete it (the error above still names the existing ride)
      }
    }
    form.querySelector("[data-form-error]").append(" ", h("a", { href: `#/rides/${existing}`, "data-existing-ride": existing },
      `Open ride ${existing}`));
  }

  cancel.addEventListener("click", async () => {
    controller?.abort();
    await Promise.all(active.map(({ file, target }) => abandonUploads(file, target)));
  });
  form.elements.rig_id.addEventListener("change", () => loadRig().catch((error) => showError(form, error)));
  form.addEventListener("change", (event) => { if (event.target.dataset?.clipKind) checkReadiness(); });

  try {
    form.elements.ridden_on.value = today();
    await Promise.all([fillOptions(form), loadRigs()]);
    if (completing) {
      const [ride, clips] = await Promise.all([get(`/api/rides/${completing}`), get(`/api/rides/${completing}/clips`)]);
      storedClips = clips.map((c) => ({ kind: c.clip_kind, camera: c.camera_role }));
      for (const name of ["horse_id", "rider_id", "gait", "direction", "ridden_on", "rig_id"]) {
        if (ride[name] != null) form.elements[name].value = String(ride[name]);
      }
      form.querySelector('[data-upload-source][value="clips"]').checked = true;
      // The ride exists: only its missing clips are sent (its details are changed on the ride page).
      for (const name of ["horse_id", "rider_id", "gait", "direction", "ridden_on", "rig_id", "notes"]) form.elements[name].disabled = true;
      for (const radio of form.querySelectorAll("[data-upload-source]")) radio.disabled = radio.value !== "clips";
      view.querySelector("h1").textContent = `Complete ride ${completing}`;
    }
    if (!completing && query?.get?.("rig")) form.elements.rig_id.value = query.get("rig");  // from a rig page
    form.querySelector("[data-clip-cards]").append(...clipCards(storedClips));
    showSource();
    await loadRig();
  } catch (error) {
    showError(form, error);
  }
  return () => controller?.abort();
}
