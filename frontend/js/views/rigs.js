// Rigs: the club's three-camera set-ups. #/rigs lists them with "add a rig" (name and its calibration
// board); #/rigs/:id is one rig: the board to print at true scale, its calibration, plumb and static
// clips per camera (resumable uploads), the calibration's quality in plain words and, per camera,
// where in the image the board has been; beside the board walk, "Calibrate with a wand": the wand's
// length and each camera's wand and close-up clips (issue 35).

import { del, get, getAll, patch, post, request } from "../api.js";
import { all, announce, busy, control, field, formValues, h, maybeOne, messageOf, one, page, showError } from "../dom.js";
import { poll } from "../poll.js";
import { navigate } from "../router.js";
import { plainReason } from "../form-errors.js";
import { can } from "../session.js";
import { uploadResumable } from "../uploader.js";

/** @typedef {import("../api-types").RigDetail} RigDetail */
/** @typedef {import("../api-types").BoardIn} Board */
/** @typedef {import("../api-types").RecordingOut} RecordingOut */
/** @typedef {import("../api-types").CameraCheckOut} CameraCheckOut */
/** @typedef {import("../api-types").BoardTypeOut} BoardType */
/** @typedef {{kind: string, label: string}} ClipSet a kind of clip a rig holds, and its words */
/** @typedef {import("../api-types").CalibrationReportOut} CalibrationReport what GET /api/rigs/{id}/calibration-report answers */
/** @typedef {import("../api-types").CameraCoverageOut} Coverage where in one camera's image the board has been */

/**
 * A rig's board: the BoardIn it was given (RigOut.board, which the schema leaves an open object).
 * @param {{board: Record<string, unknown> | null}} rig
 */
function boardOf(rig) {
  return /** @type {Board | null} */ (rig.board);
}

export const CAMERAS = ["left", "middle", "right"];
/** @type {ClipSet[]} */
const RIG_CLIPS = [
  { kind: "calibration", label: "Calibration (board moved through the view)" },
  { kind: "plumb", label: "Plumb line" },
  { kind: "static", label: "Static (horse standing still)" },
];
// The wand way's clips: the wand waved by all cameras at once, and a small board close to each camera.
/** @type {ClipSet[]} */
const WAND_CLIPS = [
  { kind: "wand", label: "Wand (waved along the track, all cameras at once)" },
  { kind: "close_up", label: "Close-up board (this camera alone)" },
];
const CLIP_LABELS = Object.fromEntries([...RIG_CLIPS, ...WAND_CLIPS].map((c) => [c.kind, c.label]));

// The kinds of calibration board and the fields each adds (GET /api/board-types, the board registry's):
// the form's choice of kind and its fields are made from them, never listed here.
/** @type {Promise<BoardType[]> | null} */
let boardTypesLoading = null;

/** @returns {Promise<BoardType[]>} */
function boardTypes() {
  if (!boardTypesLoading) {
    /** @type {Promise<BoardType[]>} */
    const loading = get("/api/board-types");
    boardTypesLoading = loading.catch((error) => {
      boardTypesLoading = null;
      throw error;
    });
  }
  return boardTypesLoading;
}

/**
 * The form field of one of a kind's own fields: a number, a text, a choice of the offered texts or a flag.
 * @param {HTMLSelectElement} select
 * @param {BoardType} type
 * @param {BoardType["options"][number]} option
 */
function boardOptionField(select, type, option) {
  const id = `${select.id}-${type.kind}-${option.name}`;
  let input;
  if (option.value === "flag") input = h("input", { id, name: option.name, type: "checkbox", value: "true" });
  else if (option.offered.length) {
    input = h("select", { id, name: option.name },
      option.offered.map((value, i) => h("option", { value }, i === 0 ? `${value} (default)` : value)));
  } else if (option.value === "number") {
    input = h("input", { id, name: option.name, type: "number", step: "0.1", min: option.greater_than ?? undefined,
      max: option.at_most ?? undefined, placeholder: option.unset || undefined, "data-kind": "float" });
  } else input = h("input", { id, name: option.name, type: "text", placeholder: option.unset || undefined });
  return h("div", { class: "field", dataset: { boardKind: type.kind }, hidden: true }, h("label", { for: id }, option.label), input);
}

/**
 * The board section of a board form: kind, grid and the chosen kind's own fields as their types say.
 * @param {Record<string, string | number>} values
 * @returns {Promise<Board>}
 */
async function boardFrom(values) {
  /** @type {Board & Record<string, unknown>} */
  const board = {
    kind: /** @type {Board["kind"]} */ (values.kind || "checkerboard"), // the form's select: the API's kinds
    inner_corners: [Number(values.cols), Number(values.rows)],
    square_mm: Number(values.square_mm),
  };
  const type = (await boardTypes()).find((t) => t.kind === board.kind);
  for (const option of type?.options ?? []) {
    const raw = values[option.name];
    if (raw === undefined) continue;
    board[option.name] = option.value === "number" ? Number(raw) : option.value === "flag" ? raw === "true" : raw;
  }
  if (!(board.inner_corners[0] >= 2 && board.inner_corners[1] >= 2)) throw new Error("The board needs at least 2 \u00d7 2 inner corners.");
  if (!(board.square_mm > 0)) throw new Error("Give the size of one square in millimetres.");
  return board;
}

/**
 * Fill the form's choice of kind and its kinds' fields; only the chosen kind's show (and are sent).
 * @param {HTMLFormElement} form
 */
async function wireBoardKind(form) {
  const select = field(form, "kind", HTMLSelectElement);
  const types = await boardTypes();
  select.replaceChildren(...types.map((t) => h("option", { value: t.kind }, t.label)));
  one(form, "[data-board-options]").replaceChildren(
    ...types.flatMap((t) => t.options.map((option) => boardOptionField(select, t, option))));
  const show = () => {
    one(form, "[data-board-kind-hint]").textContent = types.find((t) => t.kind === select.value)?.short ?? "";
    for (const div of all(form, "[data-board-kind]")) {
      div.hidden = div.dataset.boardKind !== select.value;
      for (const input of div.querySelectorAll("input, select")) {
        if (input instanceof HTMLInputElement || input instanceof HTMLSelectElement) input.disabled = div.hidden;
      }
    }
  };
  select.addEventListener("change", show);
  show();
}

// ------------------------------------------------------------------------------------------- list

/** @param {HTMLElement} view */
export async function mountRigs(view) {
  view.append(page("rigs"));
  const body = one(view, "[data-rig-rows]");
  const form = one(view, "[data-rig-form]", HTMLFormElement);
  await wireBoardKind(form);
  form.hidden = !can("rig.create");
  /** @type {import("../api-types").RigOut[]} */
  const rigs = await getAll("/api/rigs");
  body.replaceChildren(...(rigs.length ? rigs.map((rig) => h("tr", {},
    h("th", { scope: "row" }, h("a", { href: `#/rigs/${rig.id}` }, rig.name)),
    h("td", {}, rig.recorded_on || ""),
    h("td", {}, rig.board_text ?? ""),
    h("td", {}, h("span", { class: `status status-${rig.calibrated ? "done" : "queued"}` },
      rig.calibrated ? "calibrated" : "not calibrated")),
  )) : [h("tr", {}, h("td", { colspan: 4, class: "hint" }, "No rigs yet: add the rig your cameras form below."))]));
  form.addEventListener("submit", (event) => {
    event.preventDefault();
    showError(form, null);
    busy(form, async () => {
      try {
        const values = formValues(form);
        if (!values.name) throw new Error("Give the rig a name (e.g. \u201cIndoor arena, three phones\u201d).");
        /** @type {import("../api-types").RigOut} */
        const rig = await post("/api/rigs", {
          name: values.name, ...(values.recorded_on ? { recorded_on: values.recorded_on } : {}), board: await boardFrom(values),
        });
        announce(`Rig ${rig.name} added.`);
        navigate(`/rigs/${rig.id}`);
      } catch (error) {
        showError(form, error);
      }
    });
  });
}

// ------------------------------------------------------------------------------------------- one rig

/**
 * @param {HTMLElement} root
 * @param {RigDetail} rig
 */
async function showBoard(root, rig) {
  const box = one(root, "[data-board-image]");
  const note = one(root, "[data-board-note]");
  one(root, "[data-board-text]").textContent = rig.board_text ?? "";
  const board = boardOf(rig);
  if (!board) {
    box.replaceChildren(h("p", { class: "hint" }, "No board described yet."));
    note.hidden = true;
    return;
  }
  const text = await request("GET", `/api/rigs/${rig.id}/board.svg`, { headers: { Accept: "image/svg+xml" } });
  const svg = new DOMParser().parseFromString(String(text), "image/svg+xml").documentElement;
  // Printed at these sizes (print stylesheet); on screen it shrinks to the page.
  box.style.setProperty("--board-width", svg.getAttribute("width"));
  box.style.setProperty("--board-height", svg.getAttribute("height"));
  box.replaceChildren(document.importNode(svg, true));
  note.hidden = false;
  one(note, "[data-square-mm]").textContent = `${board.square_mm} mm`;
  showBoardSizes(root, await get(`/api/rigs/${rig.id}/board-sizes`));
}

/** @type {(value: unknown, digits?: number) => string} */
const fmt = (value, digits = 0) => Number(value).toFixed(digits);

/**
 * The board's printed size, the papers it fits and the square each camera distance needs.
 * @param {HTMLElement} root
 * @param {import("../api-types").BoardSizesOut} sizes
 */
function showBoardSizes(root, sizes) {
  one(root, "[data-board-sizes]").hidden = false;
  one(root, "[data-board-sentences]").replaceChildren(...sizes.sentences.map((s) => h("li", {}, s)));
  one(root, "[data-board-layouts]").replaceChildren(...sizes.layouts.map((lay) => h("li", {
    class: lay.fits ? "fits" : "no-fit", dataset: { layout: lay.layout } },
  h("strong", {}, `${lay.label}: `),
  lay.layout === "a4-tiles"
    ? `${lay.sheets} sheets with crop marks and a 100 mm ruler each; squares of ${fmt(lay.largest_square_mm, 0)} mm, found up to ${fmt(lay.reach_m, 1)} m from the camera.`
    : lay.fits
      ? `fits. This pattern could have squares up to ${fmt(Math.floor(lay.largest_square_mm))} mm on it (found up to ${fmt(lay.reach_m, 1)} m away).`
      : `too small for ${fmt(sizes.square_mm)} mm squares; with this pattern it takes squares up to ${fmt(Math.floor(lay.largest_square_mm))} mm (cameras up to ${fmt(lay.reach_m, 1)} m away).`)));
  const select = one(root, "[data-print-layout]", HTMLSelectElement);
  const previous = select.value;
  const fitting = sizes.layouts.filter((lay) => lay.fits);
  select.replaceChildren(...fitting.map((lay) => h("option", { value: lay.layout }, lay.label)));
  // The smallest single sheet that fits, else the tiles: what an office printer can do first.
  select.value = fitting.some((lay) => lay.layout === previous) ? previous : fitting[0].layout;
}

/**
 * @param {RigDetail} rig
 * @param {RecordingOut | undefined} clip the rig's clip of this kind and camera
 * @param {string} kind
 * @param {string} camera
 * @param {() => Promise<void>} onUploaded
 */
function clipCell(rig, clip, kind, camera, onUploaded) {
  const id = `rig-clip-${kind}-${camera}`;
  const input = h("input", { id, type: "file", accept: "video/*,.mp4,.mov,.avi,.mkv", dataset: { rigClip: `${kind}-${camera}` } });
  const status = h("span", { class: "hint", "aria-live": "polite" },
    clip ? `${clip.original_filename || "uploaded"} \u00b7 ${clip.width}\u00d7${clip.height} px, ${Number(clip.fps).toFixed(1)} fps` : "not uploaded");
  const error = h("p", { class: "form-error", role: "alert", hidden: true });
  input.addEventListener("change", async () => {
    if (!input.files?.length) return;
    const file = input.files[0];
    error.hidden = true;
    input.disabled = true;
    try {
      status.textContent = "uploading\u2026";
      // the rig page's kinds and cameras are the API's (RIG_CLIPS, WAND_CLIPS, CAMERAS)
      const target = /** @type {import("../uploader.js").UploadTarget} */ ({ target: "rig_clip", rig_id: rig.id, clip_kind: kind, camera });
      await uploadResumable(file, target, {
        onProgress: (sent) => { status.textContent = `uploading ${Math.floor((100 * sent) / Math.max(file.size, 1))} %`; },
      });
      announce(`The ${kind.replace("_", "-")} clip of the ${camera} camera is uploaded.`);
      await onUploaded();
    } catch (e) {
      error.textContent = messageOf(e);
      error.hidden = false;
      status.textContent = clip ? "the earlier clip is kept" : "not uploaded";
    } finally {
      input.disabled = false;
      input.value = "";
    }
  });
  return h("div", { class: "rig-clip", dataset: { clipKind: kind, camera } },
    h("label", { for: id }, CLIP_LABELS[kind]), status,
    h("span", { "data-permission": "rig.create" }, input), error);
}

/**
 * @param {HTMLElement} root
 * @param {RigDetail} rig
 * @param {RecordingOut[]} clips
 * @param {() => Promise<void>} refresh
 * @param {{where?: string, kinds?: ClipSet[], label?: string}} [options]
 */
function showClips(root, rig, clips, refresh, { where = "[data-rig-clips]", kinds = RIG_CLIPS, label = "camera" } = {}) {
  const box = one(root, where);
  const uploadAllowed = can("rig.create");
  box.replaceChildren(...CAMERAS.map((camera) => h("section", { class: "camera-card", "aria-label": `${camera} ${label}` },
    h("h3", {}, `${camera[0].toUpperCase()}${camera.slice(1)} camera`),
    ...kinds.map(({ kind }) => {
      const cell = clipCell(rig, clips.find((c) => c.clip_kind === kind && c.camera_role === camera), kind, camera, refresh);
      if (!uploadAllowed) one(cell, "[data-permission]").remove();
      return cell;
    }))));
}

const SVG_NS = "http://www.w3.org/2000/svg";
/**
 * @param {string} tag
 * @param {Record<string, string | number>} attrs
 */
function svgEl(tag, attrs) {
  const el = document.createElementNS(SVG_NS, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, String(v));
  return el;
}

/**
 * One camera's image frame with the board corners seen (dots) and their hull.
 * @param {string} camera
 * @param {Coverage} entry
 */
function coveragePicture(camera, entry) {
  const [w, h_] = entry.image_size;
  const svg = svgEl("svg", { viewBox: `0 0 ${w} ${h_}`, role: "img", class: "coverage",
    "aria-label": `Where the board was in the ${camera} camera's image` });
  svg.append(svgEl("rect", { x: 0, y: 0, width: w, height: h_, class: "coverage-frame" }));
  // The ninths of the image no corner reached, tinted: where distances are least certain.
  if (entry.missed) {
    const reached = new Set((entry.corners_px || []).map(([x, y]) => `${Math.min(2, Math.floor((3 * y) / h_))},${Math.min(2, Math.floor((3 * x) / w))}`));
    for (let r = 0; r < 3; r += 1) {
      for (let c = 0; c < 3; c += 1) {
        if (!reached.has(`${r},${c}`)) svg.append(svgEl("rect", { x: (c * w) / 3, y: (r * h_) / 3, width: w / 3, height: h_ / 3, class: "coverage-missed" }));
      }
    }
  }
  for (const f of [1, 2]) {
    svg.append(svgEl("line", { x1: (f * w) / 3, y1: 0, x2: (f * w) / 3, y2: h_, class: "coverage-grid" }));
    svg.append(svgEl("line", { x1: 0, y1: (f * h_) / 3, x2: w, y2: (f * h_) / 3, class: "coverage-grid" }));
  }
  if (entry.hull_px?.length) {
    svg.append(svgEl("polygon", { points: entry.hull_px.map(([x, y]) => `${x},${y}`).join(" "), class: "coverage-hull" }));
  }
  const r = Math.max(w, h_) / 250;
  for (const [x, y] of entry.corners_px || []) svg.append(svgEl("circle", { cx: x, cy: y, r, class: "coverage-dot" }));
  return svg;
}

/**
 * One camera's coverage map: the image cut in cells, each shaded by the views whose corners fell in it.
 * @param {string} camera
 * @param {CameraCheckOut} entry
 */
function checkGrid(camera, entry) {
  const [w, h_] = entry.image_size;
  const rows = entry.grid.length;
  const cols = rows ? entry.grid[0].length : 0;
  const most = Math.max(1, ...entry.grid.flat());
  const svg = svgEl("svg", { viewBox: `0 0 ${w} ${h_}`, role: "img", class: "coverage",
    "aria-label": `Coverage map of the ${camera} camera's image: ${entry.bands_missed.length ? `never reached: ${entry.bands_missed.join(", ")}` : "every third reached"}` });
  svg.append(svgEl("rect", { x: 0, y: 0, width: w, height: h_, class: "coverage-frame" }));
  entry.grid.forEach((row, r) => row.forEach((views, c) => {
    const cell = svgEl("rect", { x: (c * w) / cols, y: (r * h_) / rows, width: w / cols, height: h_ / rows,
      class: views ? "check-cell" : "coverage-missed" });
    if (views) cell.setAttribute("fill-opacity", String(0.15 + (0.75 * views) / most));
    svg.append(cell);
  }));
  for (const f of [1, 2]) {
    svg.append(svgEl("line", { x1: (f * w) / 3, y1: 0, x2: (f * w) / 3, y2: h_, class: "coverage-grid" }));
    svg.append(svgEl("line", { x1: 0, y1: (f * h_) / 3, x2: w, y2: (f * h_) / 3, class: "coverage-grid" }));
  }
  return svg;
}

/**
 * The board's distances from the camera: one bar per distance bin, as tall as its views.
 * @param {string} camera
 * @param {import("../api-types").DepthCoverageOut} depth
 * @param {string} [what]
 */
function depthBars(camera, depth, what = "board") {
  const most = Math.max(1, ...depth.views);
  const n = depth.views.length;
  const bin = 30;
  const svg = svgEl("svg", { viewBox: `0 0 ${n * bin} 28`, role: "img", class: "check-depth",
    "aria-label": depth.near_m == null ? `No distances for the ${camera} camera`
      : `The ${what} was held ${depth.near_m.toFixed(1)} to ${Number(depth.far_m).toFixed(1)} m from the ${camera} camera` });
  depth.views.forEach((views, i) => {
    const tall = (26 * views) / most;
    svg.append(svgEl("rect", { x: i * bin + 2, y: 27 - tall, width: bin - 4, height: tall, class: "check-depth-bar" }));
  });
  svg.append(svgEl("line", { x1: 0, y1: 27.5, x2: n * bin, y2: 27.5, class: "check-depth-axis" }));
  return h("div", { class: "check-depth-box" }, svg, h("div", { class: "check-depth-scale", "aria-hidden": "true" },
    h("span", {}, "0 m"), h("span", {}, "distance from the camera"), h("span", {}, `${Number(depth.bin_edges_m[n]).toFixed(0)} m`)));
}

// One camera's check: where the board's corners (or the wand's two ends) went, over the image and in depth.
/**
 * @param {string} camera
 * @param {CameraCheckOut} entry
 * @param {"board" | "wand"} what
 */
function checkFigure(camera, entry, what) {
  const seen = what === "wand" ? `Both wand ends in ${entry.views} of ${entry.frames_sampled} frames looked at; they reached`
    : `Board in ${entry.views} of ${entry.frames_sampled} frames looked at; its corners reached`;
  const reach = !entry.views
    ? `${what === "wand" ? "Both wand ends were" : "The board was"} not found in any of the ${entry.frames_sampled} frames looked at.`
    : `${seen} ${Math.round(100 * entry.reach_x[0])}-${Math.round(100 * entry.reach_x[1])} % across and ${Math.round(100 * entry.reach_y[0])}-${Math.round(100 * entry.reach_y[1])} % down the image.`;
  return h("figure", { class: `coverage-figure check-camera${entry.film_again ? " film-again" : ""}`, dataset: { checkCamera: camera, checkWhat: what } },
    checkGrid(camera, entry), depthBars(camera, entry.depth, what),
    h("figcaption", {}, h("strong", {}, `${camera[0].toUpperCase()}${camera.slice(1)} camera${what === "wand" ? "'s wand clip" : ""}: ${entry.film_again ? "film again" : "good"}. `), reach,
      h("ul", { class: "check-findings" }, ...entry.findings.map((f) => h("li", { class: `severity-${f.severity}` }, f.detail)))));
}

/**
 * @param {HTMLElement} root
 * @param {import("../api-types").CalibrationCheckOut} check
 */
function showCheck(root, check) {
  const verdict = one(root, "[data-check-verdict]");
  verdict.textContent = check.checking && check.checked ? `Checking again… ${check.verdict}` : check.verdict;
  verdict.className = `check-verdict${check.checked ? (check.film_again ? " film-again" : " ready") : ""}`;
  one(root, "[data-check-cameras]").replaceChildren(
    ...Object.entries(check.cameras || {}).map(([camera, entry]) => checkFigure(camera, entry, "board")));
  // The wand's clips, once the rig has them and its wand's length (issue 35): checked the same way.
  const wand = one(root, "[data-wand-check]");
  wand.hidden = !check.wand;
  if (check.wand) {
    const words = one(wand, "[data-wand-check-verdict]");
    words.textContent = check.wand.verdict;
    words.className = `check-verdict${check.wand.film_again ? " film-again" : " ready"}`;
    one(wand, "[data-wand-check-cameras]").replaceChildren(
      ...Object.entries(check.wand.cameras || {}).map(([camera, entry]) => checkFigure(camera, entry, "wand")));
  }
  const again = one(root, "[data-check-again]");
  again.hidden = !can("ride.analyse") || check.checking || !(check.checked || check.wand);
}

/**
 * @param {RigDetail} rig
 * @param {RecordingOut[]} clips
 */
function calibrationMissing(rig, clips) {
  /** @type {string[]} */
  const missing = [];
  if (!rig.board) missing.push("The rig has no calibration board described.");
  const have = clips.filter((c) => c.clip_kind === "calibration").map((c) => c.camera_role);
  const lacking = CAMERAS.filter((c) => !have.includes(c));
  if (lacking.length) missing.push(`The calibration clip of the ${lacking.join(" and ")} camera${lacking.length > 1 ? "s is" : " is"} missing.`);
  return missing;
}

/**
 * @param {HTMLElement} root
 * @param {RigDetail} rig
 * @param {RecordingOut[]} clips
 * @param {CalibrationReport} report
 */
function showCalibration(root, rig, clips, report) {
  const status = one(root, "[data-calibration-status]");
  const words = one(root, "[data-calibration-words]");
  const flags = one(root, "[data-calibration-flags]");
  const coverage = one(root, "[data-coverage]");
  const missing = calibrationMissing(rig, clips);
  const q = report.quality;
  if (report.calibrating) status.textContent = "Calibrating now\u2026 (this page updates by itself)";
  else if (q.calibrated) status.textContent = "Calibrated: rides of this rig reuse this calibration.";
  else if (missing.length) status.textContent = `Not calibrated yet. ${missing.join(" ")}`;
  else status.textContent = "Not calibrated yet: the calibration has not run or did not succeed (see Jobs); start it again below.";
  words.replaceChildren(...(q.calibrated ? q.sentences : []).map((s) => h("li", {}, s)));
  flags.replaceChildren(...(q.calibrated ? q.flags : []).map((f) => h("li", { class: "flag" }, f)));
  coverage.replaceChildren(...Object.entries(report.coverage || {}).map(([camera, entry]) => h("figure", { class: "coverage-figure" },
    coveragePicture(camera, entry), h("figcaption", {}, h("strong", {}, `${camera}: `), entry.sentence))));
  const again = one(root, "[data-calibrate]");
  again.hidden = !can("ride.analyse") || report.calibrating || missing.length > 0;
  again.textContent = q.calibrated ? "Calibrate again" : "Calibrate now";
}

/**
 * @param {HTMLElement} root
 * @param {RigDetail} rig
 * @param {() => Promise<void>} reload
 */
function wireBoardEdit(root, rig, reload) {
  const form = one(root, "[data-board-form]", HTMLFormElement);
  form.hidden = !can("rig.change_board");
  if (form.hidden) return;
  wireBoardKind(form).then(() => {
    const board = boardOf(rig);
    if (!board) return;
    const text = (/** @type {string} */ name) => control(form, name);
    text("kind").value = String(board.kind);
    [text("cols").value, text("rows").value] = board.inner_corners.map(String);
    text("square_mm").value = String(board.square_mm);
    for (const [name, value] of Object.entries(board)) {
      const input = form.querySelector(`[data-board-kind="${board.kind}"] [name="${name}"]`);
      if (input instanceof HTMLInputElement && input.type === "checkbox") input.checked = value === true;
      else if ((input instanceof HTMLInputElement || input instanceof HTMLSelectElement) && value !== null) {
        input.value = String(value);
      }
    }
    text("kind").dispatchEvent(new Event("change"));
  }).catch((error) => showError(form, error));
  form.addEventListener("submit", (event) => {
    event.preventDefault();
    showError(form, null);
    busy(form, async () => {
      try {
        await patch(`/api/rigs/${rig.id}`, { board: await boardFrom(formValues(form)) });
        announce("Board changed.");
        await reload();
      } catch (error) {
        showError(form, error);
      }
    });
  });
}

/**
 * "Calibrate with a wand": save the wand's length when changed, then ask for the wand way; refusals in words.
 * @param {HTMLElement} root
 * @param {number} rigId
 * @param {() => RigDetail} getRig
 * @param {() => Promise<void>} reload
 */
function wireWand(root, rigId, getRig, reload) {
  const form = one(root, "[data-wand-form]", HTMLFormElement);
  const button = one(form, "[data-calibrate-wand]");
  button.hidden = !can("ride.analyse");
  field(form, "wand_length_m").disabled = !can("rig.create");
  form.addEventListener("submit", (event) => {
    event.preventDefault();
    showError(form, null);
    busy(form, async () => {
      try {
        const typed = field(form, "wand_length_m").value.trim();
        const length = typed === "" ? null : Number(typed.replace(",", "."));
        if (length !== null && length !== getRig().wand_length_m) {
          await patch(`/api/rigs/${rigId}`, { wand_length_m: Number.isFinite(length) ? length : typed });
        }
        await post(`/api/rigs/${rigId}/calibrate`, { method: "wand" });
        announce("Calibrating with the wand.");
        await reload();
      } catch (error) {
        showError(form, plainReason(error));
      }
    });
  });
}

/**
 * @param {HTMLElement} view
 * @param {Record<string, string>} params the rig's id
 */
export async function mountRig(view, params) {
  // Its own box: uploads and polls finishing after the user left look into it, not into the next page.
  const root = h("div", { class: "rig-page" });
  root.append(page("rig"));
  view.append(root);
  const rigId = Number(params.id);
  let gone = false;
  /** @type {RigDetail} */
  let rig = await get(`/api/rigs/${rigId}`);
  /** @type {RecordingOut[]} */
  let clips = [];
  /** @type {import("../poll.js").Poller | null} */
  let poller = null;
  one(root, "[data-rig-name]").textContent = rig.name;
  one(root, "[data-upload-with-rig]", HTMLAnchorElement).href = `#/upload?rig=${rigId}`;
  one(root, "[data-rig-date]").textContent = rig.recorded_on ? `Recorded on ${rig.recorded_on}` : "";

  async function refreshCalibration() {
    if (gone) return false;
    /** @type {CalibrationReport} */
    const report = await get(`/api/rigs/${rigId}/calibration-report`);
    /** @type {import("../api-types").CalibrationCheckOut} */
    const check = await get(`/api/rigs/${rigId}/calibration-check`);
    rig = await get(`/api/rigs/${rigId}`);
    if (gone) return false;
    showCalibration(root, rig, clips, report);
    showCheck(root, check);
    return report.calibrating || check.checking;
  }
  async function reload() {
    if (gone) return;
    rig = await get(`/api/rigs/${rigId}`);
    clips = await get(`/api/rigs/${rigId}/clips`);
    if (gone) return;
    await showBoard(root, rig);
    showClips(root, rig, clips, reload);
    showClips(root, rig, clips, reload, { where: "[data-wand-clips]", kinds: WAND_CLIPS, label: "camera's wand clips" });
    const length = field(one(root, "[data-wand-form]", HTMLFormElement), "wand_length_m");
    if (rig.wand_length_m != null && document.activeElement !== length) length.value = String(rig.wand_length_m);
    poller?.stop?.();
    poller = poll(refreshCalibration, { intervalMs: 3000 });
  }
  wireBoardEdit(root, rig, reload);
  wireWand(root, rigId, () => rig, reload);
  // The print page has every sheet at its size in mm (@page): the browser prints it at scale.
  one(root, "[data-print-board]").addEventListener("click", () => {
    const layout = one(root, "[data-print-layout]", HTMLSelectElement).value || "a4-tiles";
    window.open(`/api/rigs/${rigId}/board-print?layout=${encodeURIComponent(layout)}`, "_blank", "noopener");
  });
  const calibrate = one(root, "[data-calibrate]", HTMLButtonElement);
  calibrate.addEventListener("click", async () => {
    const button = calibrate;
    button.disabled = true;
    try {
      await post(`/api/rigs/${rigId}/calibrate`, {});
      await reload();
    } catch (error) {
      showError(one(root, "[data-calibration-panel]"), error);
    } finally {
      button.disabled = false;
    }
  });
  const checkAgain = one(root, "[data-check-again]", HTMLButtonElement);
  checkAgain.addEventListener("click", async () => {
    const button = checkAgain;
    button.disabled = true;
    try {
      await post(`/api/rigs/${rigId}/calibration-check`, {});
      await reload();
    } catch (error) {
      showError(one(root, "[data-check-panel]"), error);
    } finally {
      button.disabled = false;
    }
  });
  const remove = one(root, "[data-rig-delete]");
  remove.hidden = !can("rig.delete");
  remove.addEventListener("click", async () => {
    if (!window.confirm(`Delete the rig \u201c${rig.name}\u201d with its clips and calibration?`)) return;
    try {
      await del(`/api/rigs/${rigId}`);
      navigate("/rigs");
    } catch (error) {
      showError(one(root, "[data-rig-header]"), error);
    }
  });
  await reload();
  return () => {
    gone = true;
    poller?.stop?.();
  };
}
