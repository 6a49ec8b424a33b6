// Upload a ride: a bundle zip, or the clips one by one (motion clips, and static, plumb and
// calibration clips unless a calibrated rig is chosen), or a motion-capture file (C3D, TRC) analysed
// at once. Progress over all bytes, resumable.

import { ApiError, patch, post, request } from "../api.js";
import { announce, formValues, h, page, showError } from "../dom.js";
import { fillOptions } from "../options.js";
import { navigate } from "../router.js";
import { abandonUploads, uploadResumable } from "../uploader.js";

const CAMERAS = ["left", "middle", "right"];
const CLIP_SETS = [
  { kind: "motion", label: "Motion (the ride)", required: true },
  { kind: "static", label: "Static (horse standing, saddle marker visible)", required: false },
  { kind: "plumb", label: "Plumb line (gravity)", required: false },
  { kind: "calibration", label: "Calibration board", required: false },
];

function clipRows() {
  return CLIP_SETS.map((set) => h("tr", {},
    h("th", { scope: "row" }, set.label, set.required ? h("span", { class: "required" }, " (required)") : null),
    ...CAMERAS.map((camera) => {
      const id = `clip-${set.kind}-${camera}`;
      return h("td", {},
        h("label", { for: id, class: "sr-only" }, `${set.label}, ${camera} camera`),
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

export async function mountUpload(view) {
  view.append(page("upload"));
  const form = view.querySelector("[data-upload-form]");
  form.querySelector("[data-clip-rows]").append(...clipRows());
  const progressBox = form.querySelector("[data-upload-progress]");
  const progress = progressBox.querySelector("progress");
  const status = form.querySelector("[data-upload-status]");
  const label = form.querySelector("[data-upload-label]");
  const submit = form.querySelector("[data-upload-submit]");
  const cancel = form.querySelector("[data-upload-cancel]");
  let controller = null;
  let active = [];
  let pendingRideId = null;

  const source = () => form.querySelector("[data-upload-source]:checked").value;
  function showSource() {
    for (const part of form.querySelectorAll("[data-upload-part]")) part.hidden = part.dataset.uploadPart !== source();
    // The ride's own fields only matter for clips; a bundle names horse, rider, gait in ride.json.
    for (const name of ["horse_id", "rider_id", "gait", "direction", "ridden_on"]) {
      const field = form.elements[name].closest(".field");
      field.hidden = source() === "bundle";
    }
    // A motion-capture file has no cameras to calibrate.
    form.elements.rig_id.closest(".field").hidden = source() === "mocap";
  }
  for (const radio of form.querySelectorAll("[data-upload-source]")) radio.addEventListener("change", showSource);
  showSource();

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

  async function uploadBundle(values) {
    const input = form.elements.bundle;
    if (!input.files.length) throw new Error("Please choose the ride bundle (.zip).");
    const file = input.files[0];
    const target = { target: "bundle", ...(values.rig_id ? { rig_id: Number(values.rig_id) } : {}) };
    active = [{ file, target }];
    const progressOf = track(file.size);
    label.textContent = `Uploading ${file.name}`;
    const answer = await uploadResumable(file, target, { signal: controller.signal, onProgress: (b) => progressOf(file.name, b) });
    return answer?.ride?.id ?? answer?.ride_id;
  }

  async function uploadClips(values) {
    const clips = chosenClips(form);
    const missing = CAMERAS.filter((camera) => !clips.some((c) => c.kind === "motion" && c.camera === camera));
    if (missing.length) throw new Error(`Please choose the motion clip of the ${missing.join(" and ")} camera.`);
    if (!values.rig_id && !clips.some((c) => c.kind === "calibration")) {
      throw new Error("Choose a calibrated camera rig, or add the calibration clips of the three cameras.");
    }
    const fields = {
      horse_id: Number(values.horse_id), rider_id: Number(values.rider_id), gait: values.gait,
      direction: values.direction, rig_id: values.rig_id ? Number(values.rig_id) : null,
      ridden_on: values.ridden_on || null,
    };
    // After a failed attempt the ride exists already: send the clips to it again instead of a new one.
    const ride = pendingRideId ? await patch(`/api/rides/${pendingRideId}`, fields) : await post("/api/rides", fields);
    pendingRideId = ride.id;
    const progressOf = track(clips.reduce((total, c) => total + c.file.size, 0));
    active = [];
    for (const clip of clips) {
      const target = { target: "ride_clip", ride_id: ride.id, clip_kind: clip.kind, camera: clip.camera };
      active.push({ file: clip.file, target });
      label.textContent = `Uploading the ${clip.kind} clip of the ${clip.camera} camera`;
      await uploadResumable(clip.file, target, {
        signal: controller.signal, onProgress: (b) => progressOf(`${clip.kind}/${clip.camera}`, b) });
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
        strides: values.strides, filename: file.name,
      },
    });
    return answer?.ride?.id;
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
      if (error.name === "AbortError") {
        showError(form, "Upload cancelled.");
        return;
      }
      // The server's reason verbatim (e.g. 422 "... is not a zip file"), with the status for 4xx/5xx.
      showError(form, error instanceof ApiError && error.status ? `${error.message} (HTTP ${error.status})` : error.message);
    }
  });

  cancel.addEventListener("click", async () => {
    controller?.abort();
    await Promise.all(active.map(({ file, target }) => abandonUploads(file, target)));
  });

  try {
    await fillOptions(form);
  } catch (error) {
    showError(form, error);
  }
  return () => controller?.abort();
}
