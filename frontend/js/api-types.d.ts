// Written by `make api-types` (python -m saddlescope.api.frontend_types) from the API's OpenAPI schema
// (app.openapi()): do not edit. One type per schema; the JSDoc of the dashboard's modules names them,
// e.g. /** @type {import("./api-types").RideOut} */, and `make lint` checks them with tsc --checkJs.
// tests/api/test_api_frontend_types.py fails when this file is not what the schema writes now.

/** One ride of the most-alike list. */
export interface AlikeEntry {
  /** 1 = most alike */
  rank: number;
  ride: RideSummary;
  /** 1 = the same motion */
  similarity: number;
  /** the measure `similarity` is */
  measure: string | null;
  /** every measure the method reports, by name */
  measures: Record<string, unknown>;
}

/**
 * A ride's most-alike rides in the club, most alike first (all comparisons from the cache).
 * GET /api/rides/{ride_id}/similar answers it
 */
export interface AlikeOut {
  ride: RideSummary;
  markers: "saddle" | "M1" | "M2" | "M3" | "all";
  span: "stride" | "window";
  gait: "same" | "any";
  method_version: string;
  /** rides compared (analysed, in the gait asked for) */
  candidates: number;
  items: AlikeEntry[];
  not_comparable: NotComparable[];
}

/** The horse's own normal band: mean ± 2 SD over its earlier rides in the gait. */
export interface Band {
  /** earlier rides behind the band */
  n: number;
  mean: number;
  /** sample standard deviation of the earlier rides */
  sd: number;
  /** mean - 2 SD */
  low: number;
  /** mean + 2 SD */
  high: number;
}

/** ride.json's "board" (CONTRACTS section 1): kind, grid and the kind's own fields. */
export interface BoardIn {
  kind?: "checkerboard" | "charuco" | "acircles";
  inner_corners: [number, number];
  square_mm: number;
  /** Marker dictionary */
  dictionary?: string | null;
  /** Marker size (mm) */
  marker_mm?: number | null;
  /** Printed in OpenCV's legacy pattern (before 4.6) */
  legacy?: boolean | null;
  /** Circle diameter (mm) */
  circle_mm?: number | null;
}

/** One way to print the board (one sheet of a paper size, or A4 tiles). */
export interface BoardLayoutOut {
  /** a4, a3, a2, a1, a0 (one sheet) or a4-tiles */
  layout: string;
  label: string;
  sheets: number;
  /** the board at its square size fits this layout */
  fits: boolean;
  landscape: boolean;
  /** the largest square of this board's pattern that fits one sheet */
  largest_square_mm: number;
  /** how far from the camera the largest square is still resolved */
  reach_m: number;
}

/** A field a kind of board adds, and how the rig page asks for it. */
export interface BoardOptionOut {
  /** its key in the board (e.g. marker_mm) */
  name: string;
  value: "number" | "text" | "flag";
  /** the form's words for it, with its unit */
  label: string;
  /** what leaving it out means (e.g. 0.75 × square); empty: its default is none */
  unset: string;
  greater_than?: number | null;
  at_most?: number | null;
  /** a text's values to offer, the default first */
  offered: string[];
}

/**
 * The board's printed size, the layouts it fits, and which square each camera distance needs.
 * GET /api/rigs/{rig_id}/board-sizes answers it
 */
export interface BoardSizesOut {
  width_mm: number;
  height_mm: number;
  square_mm: number;
  image_width_px: number;
  hfov_deg: number;
  camera_source: "calibration" | "clips" | "assumed";
  /** pixels a square must cover for its corners to be found */
  min_square_px: number;
  /** how far from the camera this board's squares are resolved */
  reach_m: number;
  squares_needed: SquareAtDistance[];
  layouts: BoardLayoutOut[];
  sentences: string[];
}

/**
 * A kind of calibration board a rig may use.
 * GET /api/board-types answers it
 */
export interface BoardTypeOut {
  kind: string;
  label: string;
  /** what it is and when to choose it */
  short: string;
  /** pixels one square must cover in a frame for the board to be found */
  min_square_px: number;
  options: BoardOptionOut[];
}

/**
 * What the user chose for a bundle's ride at upload; each given field wins over ride.json.
 * POST /api/uploads/{upload_id}/finalize takes it
 */
export interface BundleChoice {
  /** None: the horse ride.json names (added if new) */
  horse_id?: number | null;
  /** None: the rider ride.json names (added if new) */
  rider_id?: number | null;
  gait?: "walk" | "sitting_trot" | "rising_trot" | "canter" | null;
  direction?: "CW" | "CCW" | null;
  ridden_on?: string | null;
  notes?: string | null;
  /** the rig the ride uses (over the one named at creation) */
  rig_id?: number | null;
  /** the club's saddle (None: the one ride.json names) */
  saddle_id?: number | null;
  pad?: string | null;
  /** kg; default: ride.json's, else the rider's */
  rider_weight_kg?: number | null;
}

/**
 * A ride bundle's upload finalised: the new ride, and its analysis job.
 * POST /api/uploads/{upload_id}/finalize answers it
 */
export interface BundleFinalisedOut {
  ride_id: number;
  job_id: number;
}

/**
 * A complete bundle upload's ride.json, to pre-fill the upload form (suggestions: its text, unchecked).
 * GET /api/uploads/{upload_id}/bundle-meta answers it
 */
export interface BundleMetaOut {
  horse: NamedInClubOut;
  rider: NamedInClubOut;
  gait: string | null;
  direction: string | null;
  /** ride.json's date as written */
  ridden_on: string | null;
  notes: string;
  saddle: NamedInClubOut;
  pad: string | null;
  /** kg, as ride.json writes it */
  rider_weight_kg: number | null;
}

/**
 * The ride a bundle became, and its analysis job.
 * POST /api/rides/bundle answers it
 */
export interface BundleUploaded {
  ride: RideOut;
  job_id: number;
}

/**
 * How to calibrate a rig: the board walk, a wand, or the board walk refined by the wand.
 *
 * Default: the board walk refined by the wand when the calibration and wand clips and the wand's length are
 * there, else the wand when its clips and length are, else the board walk.
 * POST /api/rigs/{rig_id}/calibrate takes it
 */
export interface CalibrateIn {
  /** board: the calibration clips; wand: the wand and close-up clips; board+wand: the calibration clips refined by the wand clips where that helps */
  method?: "board" | "wand" | "board+wand" | null;
  /** sets the rig's wand length first */
  wand_length_m?: number | null;
}

/**
 * The rig's calibration clips checked before anyone rides (``checked`` False until the first check).
 * GET /api/rigs/{rig_id}/calibration-check answers it
 */
export interface CalibrationCheckOut {
  checked: boolean;
  /** a check is queued or running */
  checking: boolean;
  film_again?: boolean | null;
  verdict: string;
  /** how long the check took */
  seconds?: number | null;
  /** camera -> the recording id checked */
  clips?: Record<string, number>;
  cameras?: Record<string, CameraCheckOut>;
  /** the wand clips' check, once the rig has wand clips and its wand's length (the same per camera: where the wand's ends went) */
  wand?: WandCheckOut | null;
}

/** A rig's calibration in plain words: each number with its grade, and sentences a club can act on. */
export interface CalibrationQualityOut {
  calibrated: true;
  /** the worst camera's reprojection r.m.s.; null: no camera says */
  reprojection_px: number | null;
  /** how far the rebuilt board squares are off */
  board_square_error_mm: number | null;
  /** good under 0.5 px, fair under 1 px, else poor */
  reprojection_grade: "good" | "fair" | "poor" | null;
  /** good within 0.5 mm, fair within 1 mm, else poor */
  square_grade: "good" | "fair" | "poor" | null;
  flags: string[];
  /** camera -> the board views its lens was fitted with */
  n_views: Record<string, number> | null;
  sentences: string[];
  /** whether a wand refined the board's calibration; null: no wand was offered */
  refined_by_wand: boolean | null;
}

/**
 * A rig's calibration in plain words, and per camera where in the image the board has been.
 * GET /api/rigs/{rig_id}/calibration-report answers it
 */
export interface CalibrationReportOut {
  quality: NotCalibratedOut | CalibrationQualityOut;
  /** camera -> where its board has been */
  coverage: Record<string, CameraCoverageOut>;
  /** a calibrate_rig job is queued or running */
  calibrating: boolean;
}

/** One camera's calibration clip checked: coverage over the image and depth, reach, findings. */
export interface CameraCheckOut {
  camera: string;
  image_size: [number, number];
  frames_sampled: number;
  /** sampled frames in which the board was found */
  views: number;
  /** rows x columns of the image: views whose corners fell in each cell */
  grid: number[][];
  /** the thirds of the image no corner reached, in words */
  bands_missed: string[];
  corners_missed: string[];
  /** leftmost and rightmost corner, shares of the width */
  reach_x: [number, number];
  /** topmost and lowest corner, shares of the height */
  reach_y: [number, number];
  /** the corners' outline as a share of the image */
  hull_fraction: number;
  depth: DepthCoverageOut;
  film_again: boolean;
  findings: CheckFindingOut[];
}

/** Where in one camera's image the board has been (the lens is only known there). */
export interface CameraCoverageOut {
  /** width and height, px */
  image_size: [number, number];
  /** the board corners seen (a sample), px */
  corners_px: [number, number][];
  /** their convex hull, px; null: not stored */
  hull_px: [number, number][] | null;
  /** the hull's share of the image */
  area_fraction: number | null;
  /** the ninths of the image no corner reached, in words; null: the corners are not stored for this calibration */
  missed: string[] | null;
  sentence: string;
}

/** One finding of the check: its code (saddlescope.core.findings), severity, sentence and what to do. */
export interface CheckFindingOut {
  code: string;
  severity: "ok" | "check" | "problem";
  /** the sentence with its numbers */
  detail: string;
  /** one sentence a club can act on */
  advice: string;
}

/**
 * A clip's upload finalised: its recording, and the job the clip let start.
 * POST /api/uploads/{upload_id}/finalize answers it
 */
export interface ClipFinalisedOut {
  recording_id: number;
  /** null: nothing to start yet (or a job already queued or running) */
  job_id: number | null;
  /** a ride's clip that started no job: what the ride still needs (absent otherwise) */
  missing?: string[] | null;
}

/**
 * The clip stored, and the job it started (if it completed a set).
 * PUT /api/rides/{ride_id}/clips/{clip_kind}/{camera} answers it
 * PUT /api/rigs/{rig_id}/clips/{clip_kind}/{camera} answers it
 */
export interface ClipUploaded {
  recording: RecordingOut;
  /** the job this upload started (the set of clips became complete) */
  job_id: number | null;
}

/**
 * A new club and its first user, who becomes its admin.
 * POST /api/clubs takes it
 */
export interface ClubCreate {
  club_name: string;
  email: string;
  password: string;
  display_name?: string;
}

/**
 * The club created, and its admin.
 * POST /api/clubs answers it
 */
export interface ClubCreated {
  club: ClubOut;
  user: UserOut;
}

/** A club. */
export interface ClubOut {
  id: number;
  name: string;
  created_at: string;
}

/**
 * The club's horses compared within one gait.
 * GET /api/comparison answers it
 */
export interface ComparisonOut {
  gait: string;
  /** only rides in this saddle (None: all) */
  saddle_id?: number | null;
  rides: number;
  /** rides too uncertain for a decision, not averaged */
  uncertain_left_out?: number;
  indicators: Record<string, HorsesInGait>;
}

/** The horse's rides in one gait, oldest first. */
export interface ConsistencyGait {
  gait: "walk" | "sitting_trot" | "rising_trot" | "canter";
  rides: ConsistencyRide[];
  mean_vs_previous: number | null;
}

/**
 * A horse's consistency: each ride against its own earlier rides, per gait.
 * GET /api/horses/{horse_id}/consistency answers it
 */
export interface ConsistencyOut {
  horse_id: number;
  horse: string;
  markers: "saddle" | "M1" | "M2" | "M3" | "all";
  span: "stride" | "window";
  method_version: string;
  gaits: ConsistencyGait[];
}

/** A ride of the horse against its earlier rides in the gait. */
export interface ConsistencyRide {
  ride: RideSummary;
  /** earlier rides in this gait */
  earlier: number;
  vs_previous: number | null;
  mean_vs_earlier: number | null;
  min_vs_earlier: number | null;
}

/**
 * Riders' grades against the indicators.
 * GET /api/grades/correlation answers it
 */
export interface CorrelationOut {
  gait: string | null;
  grades: number;
  /** per indicator: n, pearson_r, pearson_p, spearman_rho, intervals, expected_sign, points; min_points and withheld_reason (the coefficients are null on fewer than min_points points) */
  indicators: Record<string, Record<string, unknown>>;
}

/** How the series were thinned: every `step`-th of `samples` samples, for at most `max_points`. */
export interface Decimation {
  step: number;
  samples: number;
  max_points: number;
}

/** The distances the board was held at from the camera: a histogram of views over distance bins. */
export interface DepthCoverageOut {
  /** 10th percentile of the views' distances */
  near_m: number | null;
  /** 90th percentile of the views' distances */
  far_m: number | null;
  bin_edges_m: number[];
  views: number[];
}

/** Where the two motions differ: per track (spatial) and per stretch of the stride (temporal). */
export interface Differences {
  /** what the stretches cut: 'stride phase' for rides */
  time_base: string;
  /** equal stretches of the stride, the first from the first ride's start */
  stretches: number;
  per_marker: MarkerDifference[];
  /** RMS distance over the tracks in each stretch */
  per_stretch_mm: number[];
  most_different_marker: string;
  /** index into per_stretch_mm */
  most_different_stretch: number;
}

/**
 * Which parts of a direct upload the bucket has (a part of the wrong size is missing: send it again).
 * GET /api/uploads/{upload_id}/parts answers it
 */
export interface DirectPartsOut {
  transport: "s3-parts";
  part_bytes: number;
  parts_total: number;
  parts: PartOut[];
  /** the bytes of the parts in order from the first */
  offset_bytes: number;
}

/** An error's reason, in words for the user. */
export interface ErrorOut {
  detail: string;
  /** 409 for clips uploaded again: the ride they already are */
  ride_id?: number | null;
}

/** Why a job failed, in one sentence a club can act on, and what the ride page offers to do. */
export interface FailureOut {
  /** one plain sentence naming the clip and camera where known */
  sentence: string;
  action: "replace_clip" | "recalibrate_rig" | "film_again" | "run_again";
  /** the camera whose clip failed */
  camera: "left" | "middle" | "right" | null;
  /** the clip that failed */
  clip_kind: "calibration" | "plumb" | "static" | "motion" | null;
}

/** One indicator of one horse, per gait. */
export interface GaitComparison {
  unit: string;
  gaits: GroupStats[];
}

/**
 * What one code the service uses means to a person (services/glossary.py).
 * GET /api/glossary answers it
 */
export interface GlossaryEntryOut {
  kind: "indicator" | "gait" | "direction" | "job_kind" | "job_stage" | "clip_kind" | "camera" | "gravity_source" | "similarity_method" | "saddle_type" | "caveat";
  /** the code as the API and the stored data carry it, never shown on a page */
  code: string;
  /** what a page shows instead of the code (W_b, W_k, W_d as subscripts) */
  label: string;
  /** the unit of the values ('' where none) */
  unit: string;
  /** one line on what it means ('' where the label says it all) */
  short: string;
  /** an expert indicator: folded under 'expert detail', after the headline numbers */
  expert: boolean;
}

/**
 * A rider's comfort grade of a ride.
 * POST /api/grades takes it
 */
export interface GradeIn {
  ride_id: number;
  rider_id: number;
  /** 1 = very uncomfortable ... 5 = very comfortable */
  grade: number;
  comment?: string;
}

/**
 * A rider's comfort grade of a ride.
 * GET /api/grades/{grade_id} answers it
 * PATCH /api/grades/{grade_id} answers it
 * POST /api/grades answers it
 */
export interface GradeOut {
  id: number;
  ride_id: number;
  rider_id: number;
  grade: number;
  comment: string;
  created_at: string;
}

/**
 * Changes to a grade (unset fields stay).
 * PATCH /api/grades/{grade_id} takes it
 */
export interface GradeUpdate {
  grade?: number | null;
  comment?: string | null;
}

/** An indicator's statistics over the rides of one group. */
export interface GroupStats {
  group: string;
  n: number;
  mean: number | null;
  std: number | null;
  min: number | null;
  max: number | null;
}

export interface HTTPValidationError {
  detail?: ValidationError[];
}

/**
 * Whether the service can work: the database, the job queue and the storage (admins: details).
 * GET /api/health/details answers it
 */
export interface HealthOut {
  status: "ok" | "degraded" | "error";
  /** "Service OK" or "Service degraded: <what a club cannot do now>" */
  summary: string;
  mode: "embedded" | "celery";
  version: string;
  /** database, broker and storage */
  parts: Record<string, PartHealth>;
}

/**
 * The public health answer: one line and each part ok or not; no paths, versions or addresses.
 * GET /api/health answers it
 */
export interface HealthSummaryOut {
  status: "ok" | "degraded" | "error";
  /** "Service OK" or "Service degraded: <what a club cannot do now>" */
  summary: string;
  /** database, broker and storage: ok or not */
  parts: Record<string, PartState>;
}

/**
 * One horse's indicators across gaits.
 * GET /api/horses/{horse_id}/comparison answers it
 */
export interface HorseComparisonOut {
  horse_id: number;
  horse: string;
  rides: number;
  /** rides too uncertain for a decision, not averaged */
  uncertain_left_out?: number;
  indicators: Record<string, GaitComparison>;
}

/** An indicator's statistics over one horse's rides. */
export interface HorseGroupStats {
  group: string;
  n: number;
  mean: number | null;
  std: number | null;
  min: number | null;
  max: number | null;
  horse_id: number | null;
  horse: string;
}

/**
 * A new horse.
 * POST /api/horses takes it
 */
export interface HorseIn {
  name: string;
  breed?: string | null;
  birth_year?: number | null;
  /** height at the withers in metres (1.62), or with its unit: "162 cm", "15.2 hh" (hands) */
  height_withers_m?: number | string | null;
}

/**
 * A horse of the club.
 * GET /api/horses/{horse_id} answers it
 * PATCH /api/horses/{horse_id} answers it
 * POST /api/horses answers it
 */
export interface HorseOut {
  id: number;
  name: string;
  breed: string | null;
  birth_year: number | null;
  height_withers_m: number | null;
  created_at: string;
}

/**
 * Two analysed rides of one horse side by side.
 * GET /api/horses/{horse_id}/ride-pair answers it
 * (the schema saddlescope__api__horse_profile_schemas__PairOut)
 */
export interface HorseProfilePairOut {
  horse_id: number;
  horse: string;
  a: PairRide;
  b: PairRide;
  b_is_later: boolean;
  indicators: PairIndicator[];
}

/**
 * One horse's saddles in one gait compared.
 * GET /api/horses/{horse_id}/saddles answers it
 */
export interface HorseSaddlesOut {
  horse_id: number;
  horse: string;
  gait: "walk" | "sitting_trot" | "rising_trot" | "canter";
  include_uncertain: boolean;
  /** rides too uncertain for a decision, not counted */
  uncertain_left_out: number;
  /** analysed rides with no saddle recorded */
  without_saddle: number;
  units: Record<string, string>;
  labels: Record<string, string>;
  saddles: SaddleStats[];
  differences: SaddleDifference[];
  /** how the intervals and the verdict are computed */
  method: string;
}

export type HorseSort = "id" | "-id" | "name" | "-name" | "breed" | "-breed" | "birth_year" | "-birth_year" | "height_withers_m" | "-height_withers_m" | "created_at" | "-created_at";

/**
 * Changes to a horse (unset fields stay).
 * PATCH /api/horses/{horse_id} takes it
 */
export interface HorseUpdate {
  name?: string | null;
  breed?: string | null;
  birth_year?: number | null;
  /** height at the withers in metres (1.62), or with its unit: "162 cm", "15.2 hh" (hands) */
  height_withers_m?: number | string | null;
}

/** One indicator within a gait, per horse. */
export interface HorsesInGait {
  unit: string;
  horses: HorseGroupStats[];
}

export type IndicatorKey = "acc_y_wb_rms" | "acc_y_wk_rms" | "vdv_y_wb" | "vdv_y_wk" | "acc_y_max" | "crest_factor_y" | "t_a8_action_wb_h" | "d_a8_action_wb_km" | "t_a8_action_wk_h" | "d_a8_action_wk_km" | "t_a8_limit_wb_h" | "d_a8_limit_wb_km" | "t_a8_limit_wk_h" | "d_a8_limit_wk_km" | "t_vdv_action_wb_h" | "d_vdv_action_wb_km" | "t_vdv_action_wk_h" | "d_vdv_action_wk_km" | "t_vdv_limit_wb_h" | "d_vdv_limit_wb_km" | "t_vdv_limit_wk_h" | "d_vdv_limit_wk_km" | "vel_x_avg_kmh" | "amplitude_y_m" | "stride_frequency_hz" | "crest_factor_y_wk" | "acc_y_wb_peak" | "acc_y_wk_peak" | "acc_y_rms" | "mtvv_y_wb" | "mtvv_y_wk" | "vdv_ratio_y_wb" | "duration_s" | "acc_x_wd_rms" | "vdv_x_wd" | "acc_x_max" | "acc_z_wd_rms" | "vdv_z_wd" | "acc_z_max" | "t_a8_action_worst_h" | "d_a8_action_worst_km" | "t_a8_limit_worst_h" | "d_a8_limit_worst_km" | "t_vdv_action_worst_h" | "d_vdv_action_worst_km" | "t_vdv_limit_worst_h" | "d_vdv_limit_worst_km";

/**
 * What an indicator key means: unit, label, thesis name and which way is more comfortable.
 * GET /api/indicators answers it
 */
export interface IndicatorOut {
  key: string;
  unit: string;
  label: string;
  thesis_name: string | null;
  better: "lower" | "higher" | null;
  /** one of the thesis's eight comfort indicators */
  comfort: boolean;
}

/**
 * A job to queue.
 * POST /api/jobs takes it
 */
export interface JobCreate {
  /** job kind, e.g. 'analyze', 'calibrate_rig', 'probe' or 'selftest' */
  kind: string;
  /** the ride to work on (probe, analyze) */
  ride_id?: number | null;
  /** the rig to work on (probe, calibrate_rig) */
  rig_id?: number | null;
  /** kind-specific options, e.g. {'steps': 5} for selftest (at most 1048576 bytes as JSON) */
  payload?: Record<string, unknown>;
}

/**
 * A job kind this server runs, with its stages in order.
 * GET /api/jobs/kinds answers it
 */
export interface JobKindOut {
  name: string;
  stages: string[];
  needs_ride: boolean;
  description: string;
}

/**
 * A job: its status, progress, per-stage timings and error.
 * GET /api/jobs/{job_id} answers it
 * POST /api/jobs answers it
 * POST /api/jobs/{job_id}/cancel answers it
 * POST /api/jobs/{job_id}/retry answers it
 * POST /api/rides/{ride_id}/analyze answers it
 * POST /api/rides/{ride_id}/calibrate-rig answers it
 * POST /api/rigs/{rig_id}/calibrate answers it
 * POST /api/rigs/{rig_id}/calibration-check answers it
 */
export interface JobOut {
  id: number;
  kind: string;
  status: "queued" | "running" | "done" | "failed" | "cancelled";
  /** stage running now (with a detail after ': ') */
  stage: string | null;
  progress: number;
  /** wall seconds per finished stage, and 'total' */
  timings_s: Record<string, number>;
  error: string | null;
  ride_id: number | null;
  rig_id: number | null;
  payload: Record<string, unknown>;
  attempts: number;
  code_version: string | null;
  host: string | null;
  created_at: string;
  started_at: string | null;
  finished_at: string | null;
  /** what an unfinished job waits for, e.g. 'waiting for a worker: ...' when no worker is alive or its worker stopped sending heartbeats */
  note?: string | null;
  /** progress as a whole percentage */
  progress_percent?: number;
  /** what the job is doing, in plain words */
  stage_label?: string;
  /** the user who made the job's ride (may cancel and retry it); None: admins only */
  owner_id?: number | null;
  /** a failed job's reason in plain words */
  failure?: FailureOut | null;
  /** a running job's expected remaining time, from its progress so far (None: not running, too early) */
  remaining_s?: number | null;
  /** how long a finished job ran */
  duration_s?: number | null;
  /** the job's ride as a club names it ('Bramble, canter') */
  ride_label?: string | null;
}

export type JobSort = "id" | "-id" | "created_at" | "-created_at" | "status" | "-status" | "kind" | "-kind";

/** One horse's place in a ranking. */
export interface LeaderboardEntry {
  rank: number;
  horse_id: number | null;
  horse: string;
  /** rides behind the mean */
  n: number;
  mean: number | null;
  std: number | null;
  min: number | null;
  max: number | null;
  /** max - min over the horse's rides */
  spread: number | null;
  /** rides behind the mean that are too uncertain for a decision */
  uncertain_rides?: number;
}

/**
 * The club's horses ranked in a gait by an indicator, most comfortable first.
 * GET /api/leaderboard answers it
 */
export interface LeaderboardOut {
  gait: string;
  indicator: string;
  unit: string;
  better: "lower" | "higher";
  rides: number;
  entries: LeaderboardEntry[];
  include_uncertain?: boolean;
  /** only rides in this saddle (None: all) */
  saddle_id?: number | null;
  /** rides too uncertain, with the reason */
  uncertain?: UncertainRide[];
}

/** How far one track of the first ride is from the second's once both are in stride phase. */
export interface MarkerDifference {
  /** saddle, M1, M2 or M3 */
  marker: string;
  /** RMS distance of the phase-aligned mean strides */
  rms_mm: number;
  /** the track's DTW similarity (1 = the same motion) */
  dtw: number;
  /** RMS distance in each stretch of the stride, in order */
  per_stretch_mm: number[];
}

/** ride.json's "markers": how many markers on the horse, the plumb line and the saddle. */
export interface MarkersIn {
  horse?: number;
  plumb?: number;
  saddle?: number;
}

/**
 * The signed-in user and their club.
 * GET /api/auth/me answers it
 */
export interface MeOut {
  user: UserOut;
  club: ClubOut;
  /** per action of docs/permissions.md what this user may do: 'all' (any such thing), 'own' (only what they made) or 'none'; the dashboard hides controls the user may not use */
  permissions?: Record<string, string>;
}

/** An indicator over a group of rides: n, the mean and its 95 % interval (None below two rides). */
export interface MeanWithInterval {
  n: number;
  mean: number | null;
  sd: number | null;
  low: number | null;
  high: number | null;
}

/**
 * The analysed ride a motion-capture file became: its period, indicators and what was chosen.
 * POST /api/mocap answers it
 */
export interface MocapRideOut {
  ride: RideOut;
  period_s: number;
  indicators: Record<string, number>;
  flags: string[];
  source: Record<string, unknown>;
}

/** A horse, rider or saddle a bundle names, and the club's one of that name. */
export interface NamedInClubOut {
  /** as ride.json says it; null: ride.json names none */
  name: string | null;
  /** the club's horse, rider or saddle of that name; null: the club has none */
  id: number | null;
}

/** A rig not calibrated yet: its quality is one sentence saying so. */
export interface NotCalibratedOut {
  calibrated: false;
  sentences: string[];
}

/** A ride that could not be compared, and why. */
export interface NotComparable {
  ride: RideSummary;
  reason: string;
}

/** A chunk refused (409): its Upload-Offset is not where the upload stands, or the upload takes no more bytes. */
export interface OffsetConflictOut {
  detail: string;
  /** 409 for clips uploaded again: the ride they already are */
  ride_id?: number | null;
  /** where the upload stands: send the next chunk from here (also the Upload-Offset header); absent when it takes no more bytes */
  offset_bytes?: number | null;
}

/** The band the horse page draws across its trend, with where it comes from and its own uncertainty. */
export interface PageBand {
  /** earlier rides behind the band */
  n: number;
  mean: number;
  /** sample standard deviation of the earlier rides */
  sd: number;
  /** mean - 2 SD */
  low: number;
  /** mean + 2 SD */
  high: number;
  /** the horse's own rides, or the club's horses in the gait */
  source: "horse" | "club";
  /** horses behind the band */
  horses: number;
  /** where the band comes from, in words */
  reason: string;
  /** 95 % interval of the band's lower edge */
  low_interval_95: number[];
  /** 95 % interval of the band's upper edge */
  high_interval_95: number[];
}

/** GET /api/grades answers it */
export interface Page_GradeOut_ {
  items: GradeOut[];
  /** rows matching the filters (all pages) */
  total: number;
  limit: number;
  offset: number;
}

/** GET /api/horses answers it */
export interface Page_HorseOut_ {
  items: HorseOut[];
  /** rows matching the filters (all pages) */
  total: number;
  limit: number;
  offset: number;
}

/** GET /api/jobs answers it */
export interface Page_JobOut_ {
  items: JobOut[];
  /** rows matching the filters (all pages) */
  total: number;
  limit: number;
  offset: number;
}

/** GET /api/rides answers it */
export interface Page_RideOut_ {
  items: RideOut[];
  /** rows matching the filters (all pages) */
  total: number;
  limit: number;
  offset: number;
}

/** GET /api/riders answers it */
export interface Page_RiderOut_ {
  items: RiderOut[];
  /** rows matching the filters (all pages) */
  total: number;
  limit: number;
  offset: number;
}

/** GET /api/rigs answers it */
export interface Page_RigOut_ {
  items: RigOut[];
  /** rows matching the filters (all pages) */
  total: number;
  limit: number;
  offset: number;
}

/** GET /api/saddles answers it */
export interface Page_SaddleOut_ {
  items: SaddleOut[];
  /** rows matching the filters (all pages) */
  total: number;
  limit: number;
  offset: number;
}

/** GET /api/users answers it */
export interface Page_UserOut_ {
  items: UserOut[];
  /** rows matching the filters (all pages) */
  total: number;
  limit: number;
  offset: number;
}

/** An indicator of both rides and the second's % difference from the first. */
export interface PairIndicator {
  key: string;
  label: string;
  unit: string;
  better: "lower" | "higher" | null;
  a: number | null;
  b: number | null;
  /** (b - a) / |a| × 100; None where a is 0 or missing */
  difference_percent: number | null;
}

/** One of the two rides compared. */
export interface PairRide {
  ride_id: number;
  date: string | null;
  gait: "walk" | "sitting_trot" | "rising_trot" | "canter";
  rider: string;
}

/** The saddle-point paths (travel and mean removed, mm, motion frame) and the aligned strides. */
export interface PairView {
  paths_mm: number[][][];
  strides: StridesView | null;
  reason: string | null;
}

/** One part's health: ok or not, with what it said. */
export interface PartHealth {
  ok: boolean;
  status: "ok" | "degraded" | "error";
  detail: string;
  /** storage only: free bytes of the folder's disk */
  free_bytes?: number | null;
}

/**
 * The parts (1-based) of a direct upload to sign URLs for.
 * POST /api/uploads/{upload_id}/parts takes it
 */
export interface PartNumbers {
  numbers: number[];
}

/** A part the bucket has, of the size its place needs. */
export interface PartOut {
  number: number;
  /** bytes */
  size: number;
}

/** One part's health without its detail (what anyone may see). */
export interface PartState {
  ok: boolean;
  status: "ok" | "degraded" | "error";
  /** storage only: free bytes of the folder's disk */
  free_bytes?: number | null;
}

/**
 * Pre-signed URLs to PUT parts of a direct upload to.
 * POST /api/uploads/{upload_id}/parts answers it
 */
export interface PartUrlsOut {
  /** part number ("1") -> the URL to PUT it to */
  urls: Record<string, string>;
  /** how long the URLs work */
  expires_s: number;
  /** each part's size in bytes (the last one shorter) */
  part_bytes: number;
}

/** One pass of the horse in front of the cameras (a ride may hold several, issue 38). */
export interface PassOut {
  /** first frame with every marker, s (end_s: the last) */
  start_s: number | null;
  end_s: number | null;
  /** whole strides the pass's fits saw (0: left out) */
  strides: number | null;
  speed_m_s: number | null;
  used: boolean;
  /** why a pass was left out */
  reason: string | null;
  /** the pass's own W_b r.m.s., m/s² */
  acc_y_wb_rms: number | null;
}

/** The passes of a ride that held several: what the ride page's and the report's passes line say. */
export interface PassesOut {
  /** passes whose strides are in the ride's numbers */
  count: number;
  /** strides per used pass */
  strides: number[];
  /** e.g. "3 passes: 2, 2 and 3 strides" */
  line: string;
  /** the passes' W_b r.m.s. spread (std over mean), % */
  wb_rms_spread_percent: number | null;
  passes: PassOut[];
}

/**
 * The signed-in user's current password and the new one.
 * POST /api/auth/password takes it
 */
export interface PasswordChange {
  current_password: string;
  new_password: string;
}

/**
 * A reset token from a club admin and the new password.
 * POST /api/auth/password-reset takes it
 */
export interface PasswordResetIn {
  token: string;
  new_password: string;
}

/**
 * A one-time reset token for the user, shown once to the admin (no e-mail is sent).
 * POST /api/users/{user_id}/password-reset answers it
 */
export interface PasswordResetOut {
  /** give it to the user; it works once */
  reset_token: string;
  expires_at: string;
  /** what the user does with the token */
  how: string;
}

/**
 * 202: the comparisons are being computed by a job; poll it, then ask again.
 * GET /api/horses/{horse_id}/consistency answers it
 * GET /api/rides/{ride_id}/similar answers it
 */
export interface PendingOut {
  job: JobOut;
  /** comparisons already cached */
  cached: number;
  /** comparisons the answer needs */
  pairs: number;
  /** comparisons the job computes */
  missing: number;
  markers: "saddle" | "M1" | "M2" | "M3" | "all";
  span: "stride" | "window";
  ride_id?: number | null;
  horse_id?: number | null;
}

/** One finding of the analysis in plain words (`saddlescope.services.results.quality_notes`). */
export interface QualityNoteOut {
  /** the kind of finding, e.g. rotation.weak_axis (saddlescope.core.findings) */
  code: string;
  severity: "ok" | "check" | "problem";
  /** one sentence a club can act on */
  message: string;
  /** the pipeline's own sentence, with its numbers */
  detail: string;
}

/** The worst severity among a result's flags and one line saying it. */
export interface QualitySummaryOut {
  severity: "ok" | "check" | "problem";
  message: string;
}

/**
 * Whether a ride can be analysed now, and every clip or setting it still needs.
 * GET /api/rides/{ride_id}/readiness answers it
 */
export interface ReadinessOut {
  ready: boolean;
  /** one sentence per missing clip or setting (none: ready) */
  missing: string[];
}

/**
 * A stored clip and what probing it found.
 * GET /api/rides/{ride_id}/clips answers it
 * GET /api/rigs/{rig_id}/clips answers it
 */
export interface RecordingOut {
  id: number;
  ride_id: number | null;
  rig_id: number | null;
  clip_kind: string;
  camera_role: string;
  fps: number | null;
  frame_count: number | null;
  width: number | null;
  height: number | null;
  codec: string | null;
  size_bytes: number | null;
  sha256: string | null;
  original_filename: string | null;
  created_at: string;
}

/**
 * A ride's result as the dashboard shows it (`saddlescope.services.results.documents.view_of_document`).
 * GET /api/rides/{ride_id}/result answers it
 */
export interface ResultOut {
  ride_id: number;
  job_id: number | null;
  code_version: string | null;
  created_at: string | null;
  fps: number | null;
  period_s: number | null;
  window: Record<string, unknown> | null;
  indicators: Record<string, number | null>;
  /** 95 % interval [low, high] per indicator; null: unbounded */
  indicators_interval_95?: Record<string, (number | null)[]>;
  units: Record<string, string>;
  quality: Record<string, unknown>;
  /** the flags in plain words, most serious first */
  quality_notes?: QualityNoteOut[];
  quality_summary: QualitySummaryOut;
  /** whole strides in the analysed window */
  strides_analysed: number | null;
  /** several passes: strides per pass, spread */
  passes?: PassesOut | null;
  spectrum: SpectrumOut | null;
  calibration_checks: Record<string, unknown>;
  calibration_flags: unknown[];
  series: ResultSeries;
  /** per axis x, y, z and marker: the curve fit's goodness of fit and 95 % intervals (thesis 5.5) */
  fits?: Record<string, Record<string, unknown>[]>;
  decimation: Decimation;
}

/** The plotted series, every ``decimation.step``-th frame (vectors as [x, y, z] in the motion frame). */
export interface ResultSeries {
  t_s: number[];
  /** the saddle point S */
  position_m: unknown[];
  velocity_m_s: unknown[];
  acceleration_m_s2: unknown[];
  omega_rad_s: unknown[];
  alpha_rad_s2: unknown[];
  /** per frame, [x, y, z] of each marker; when the result has the markers */
  markers_position_m?: unknown[] | null;
  /** per frame, omega from each marker pair; when the result has them */
  omega_versions_rad_s?: unknown[] | null;
  /** per frame, which versions were left out of omega */
  omega_versions_excluded?: unknown[] | null;
  /** per frame, how close the markers' geometry is to singular */
  singularity_index_per_frame?: unknown[] | null;
  /** S's position from a Fourier (or straight-line) fit per axis */
  position_fitted_m?: unknown[] | null;
  /** measured minus fitted position */
  position_residual_m?: unknown[] | null;
  /** central differences of the measured positions */
  velocity_measured_m_s?: unknown[] | null;
  /** measured minus fitted velocity (the result's velocity_m_s) */
  velocity_residual_m_s?: unknown[] | null;
  /** second differences of the measured positions */
  acceleration_measured_m_s2?: unknown[] | null;
  /** measured minus fitted acceleration (the result's acceleration_m_s2) */
  acceleration_residual_m_s2?: unknown[] | null;
  /** vertical acceleration weighted with W_b (BS 6841), exact per harmonic */
  acc_y_wb_m_s2?: unknown[] | null;
  /** vertical acceleration weighted with W_k (ISO 2631-1), exact per harmonic */
  acc_y_wk_m_s2?: unknown[] | null;
}

/**
 * A ride with its ride.json sections, its clips and its latest job.
 * GET /api/rides/{ride_id} answers it
 */
export interface RideDetail {
  id: number;
  horse_id: number;
  /** the horse's name (so a page need not look it up by horse_id) */
  horse_name: string;
  rider_id: number;
  /** the rider's name (so a page need not look it up by rider_id) */
  rider_name: string;
  rig_id: number | null;
  gait: string;
  direction: string;
  ridden_on: string | null;
  status: string;
  notes: string;
  saddle_id?: number | null;
  pad?: string | null;
  rider_weight_kg?: number | null;
  from_bundle: boolean;
  /** the comfort indicators once analysed */
  indicators: Record<string, number | null> | null;
  created_at: string;
  /** the user who made the ride (None: not recorded) */
  created_by?: number | null;
  /** details changed since the shown result was computed (e.g. ['gait']): re-analyse to update it */
  result_outdated_by?: string[];
  meta: Record<string, unknown>;
  recordings: RecordingOut[];
  latest_job_id: number | null;
}

/**
 * A new ride (its clips are uploaded afterwards).
 * POST /api/rides takes it
 */
export interface RideIn {
  horse_id: number;
  rider_id: number;
  rig_id?: number | null;
  gait: "walk" | "sitting_trot" | "rising_trot" | "canter";
  direction: "CW" | "CCW";
  ridden_on?: string | null;
  notes?: string;
  meta?: RideMetaIn | null;
  /** the club's saddle the horse wore */
  saddle_id?: number | null;
  pad?: string | null;
  /** kg; default: the rider's weight */
  rider_weight_kg?: number | null;
}

/** Optional ride.json sections of a ride assembled from uploaded clips. */
export interface RideMetaIn {
  board?: BoardIn | null;
  markers?: MarkersIn | null;
  sync?: SyncIn | null;
}

/**
 * A ride in a list: its details, status and comfort indicators.
 * PATCH /api/rides/{ride_id} answers it
 * POST /api/rides answers it
 */
export interface RideOut {
  id: number;
  horse_id: number;
  /** the horse's name (so a page need not look it up by horse_id) */
  horse_name: string;
  rider_id: number;
  /** the rider's name (so a page need not look it up by rider_id) */
  rider_name: string;
  rig_id: number | null;
  gait: string;
  direction: string;
  ridden_on: string | null;
  status: string;
  notes: string;
  saddle_id?: number | null;
  pad?: string | null;
  rider_weight_kg?: number | null;
  from_bundle: boolean;
  /** the comfort indicators once analysed */
  indicators: Record<string, number | null> | null;
  created_at: string;
  /** the user who made the ride (None: not recorded) */
  created_by?: number | null;
  /** details changed since the shown result was computed (e.g. ['gait']): re-analyse to update it */
  result_outdated_by?: string[];
}

export type RideSort = "id" | "-id" | "ridden_on" | "-ridden_on" | "created_at" | "-created_at" | "gait" | "-gait" | "status" | "-status" | "horse_id" | "-horse_id" | "rider_id" | "-rider_id" | "direction" | "-direction" | "saddle_id" | "-saddle_id" | "rider_weight_kg" | "-rider_weight_kg" | "acc_y_wb_rms" | "-acc_y_wb_rms" | "acc_y_wk_rms" | "-acc_y_wk_rms" | "vdv_y_wb" | "-vdv_y_wb" | "vdv_y_wk" | "-vdv_y_wk" | "vel_x_avg_kmh" | "-vel_x_avg_kmh" | "amplitude_y_m" | "-amplitude_y_m" | "stride_frequency_hz" | "-stride_frequency_hz";

/** A ride as a similarity list shows it. */
export interface RideSummary {
  ride_id: number;
  horse_id: number;
  horse: string;
  gait: "walk" | "sitting_trot" | "rising_trot" | "canter";
  ridden_on: string | null;
}

/**
 * Changes to a ride (unset fields stay).
 * PATCH /api/rides/{ride_id} takes it
 */
export interface RideUpdate {
  horse_id?: number | null;
  rider_id?: number | null;
  rig_id?: number | null;
  gait?: "walk" | "sitting_trot" | "rising_trot" | "canter" | null;
  direction?: "CW" | "CCW" | null;
  ridden_on?: string | null;
  notes?: string | null;
  /** null: no saddle recorded */
  saddle_id?: number | null;
  pad?: string | null;
  /** the rider's weight in kg (20-200); null: not recorded */
  rider_weight_kg?: number | null;
}

/**
 * A new rider.
 * POST /api/riders takes it
 */
export interface RiderIn {
  name: string;
  /** the rider's own account, if any */
  user_id?: number | null;
  /** the rider's weight in kg (20-200); null: not recorded */
  weight_kg?: number | null;
}

/**
 * A rider of the club.
 * GET /api/riders/{rider_id} answers it
 * PATCH /api/riders/{rider_id} answers it
 * POST /api/riders answers it
 */
export interface RiderOut {
  id: number;
  name: string;
  user_id: number | null;
  weight_kg?: number | null;
  created_at: string;
}

export type RiderSort = "id" | "-id" | "name" | "-name" | "created_at" | "-created_at";

/**
 * Changes to a rider (unset fields stay).
 * PATCH /api/riders/{rider_id} takes it
 */
export interface RiderUpdate {
  name?: string | null;
  user_id?: number | null;
  /** the rider's weight in kg (20-200); null: not recorded */
  weight_kg?: number | null;
}

/**
 * A rig with its calibration (the result format's ``calibration`` object).
 * GET /api/rigs/{rig_id} answers it
 */
export interface RigDetail {
  id: number;
  name: string;
  recorded_on: string | null;
  cameras: Record<string, unknown>;
  board: Record<string, unknown> | null;
  /** the board in words (its kind's) */
  board_text?: string;
  /** m, between the wand's markers' centres */
  wand_length_m?: number | null;
  calibrated: boolean;
  quality: Record<string, unknown> | null;
  created_at: string;
  calibration: Record<string, unknown> | null;
}

/**
 * A new rig: a day's three-camera set-up.
 * POST /api/rigs takes it
 */
export interface RigIn {
  name: string;
  recorded_on?: string | null;
  /** model, serial, ... of each camera */
  cameras?: Partial<Record<"left" | "middle" | "right", Record<string, string>>>;
  /** the calibration board its calibration clips show */
  board?: BoardIn | null;
  /** the wand's length in m between its markers' centres (0.05-5); null: not given */
  wand_length_m?: number | null;
}

/**
 * A rig, whether it is calibrated, and its calibration's quality flags.
 * PATCH /api/rigs/{rig_id} answers it
 * POST /api/rigs answers it
 */
export interface RigOut {
  id: number;
  name: string;
  recorded_on: string | null;
  cameras: Record<string, unknown>;
  board: Record<string, unknown> | null;
  /** the board in words (its kind's) */
  board_text?: string;
  /** m, between the wand's markers' centres */
  wand_length_m?: number | null;
  calibrated: boolean;
  quality: Record<string, unknown> | null;
  created_at: string;
}

/**
 * Changes to a rig (unset fields stay).
 * PATCH /api/rigs/{rig_id} takes it
 */
export interface RigUpdate {
  name?: string | null;
  recorded_on?: string | null;
  cameras?: Partial<Record<"left" | "middle" | "right", Record<string, string>>> | null;
  board?: BoardIn | null;
  /** the wand's length in m between its markers' centres (0.05-5); null: not given */
  wand_length_m?: number | null;
}

/**
 * One saddle across the club's horses.
 * GET /api/saddles/{saddle_id}/across-horses answers it
 */
export interface SaddleAcrossHorsesOut {
  saddle: SaddleOut;
  /** every ride in the saddle, analysed or not */
  rides_total: number;
  gait: "walk" | "sitting_trot" | "rising_trot" | "canter" | null;
  include_uncertain: boolean;
  units: Record<string, string>;
  labels: Record<string, string>;
  rides: SaddleRide[];
  horses: SaddleHorseStats[];
  method: string;
}

/** Saddle b against saddle a on one indicator (Welch): b - a, its 95 % interval and the verdict. */
export interface SaddleDifference {
  indicator: string;
  saddle_a_id: number;
  saddle_a: string;
  saddle_b_id: number;
  saddle_b: string;
  /** mean of b - mean of a (None: a saddle has under two rides) */
  difference: number | null;
  low: number | null;
  high: number | null;
  p_value: number | null;
  /** the interval of the difference excludes zero */
  exceeds_uncertainty: boolean | null;
  /** the comparison in words */
  sentence: string;
}

/** The saddle on one horse in one gait. */
export interface SaddleHorseStats {
  horse_id: number;
  horse: string;
  gait: "walk" | "sitting_trot" | "rising_trot" | "canter";
  rides: number;
  indicators: Record<string, MeanWithInterval>;
}

/**
 * A new saddle of the club.
 * POST /api/saddles takes it
 */
export interface SaddleIn {
  name: string;
  maker?: string | null;
  /** gp, dressage, jump, treeless, ... */
  saddle_type?: SaddleType | null;
  /** as the maker states it ("medium", "32 cm") */
  tree_width?: string | null;
  notes?: string;
}

/**
 * A saddle of the club, with how many rides name it.
 * GET /api/saddles/{saddle_id} answers it
 * PATCH /api/saddles/{saddle_id} answers it
 * POST /api/saddles answers it
 */
export interface SaddleOut {
  id: number;
  name: string;
  maker: string | null;
  saddle_type: string | null;
  tree_width: string | null;
  notes: string;
  /** the club's rides in this saddle */
  rides?: number;
  created_at: string;
}

/** An analysed ride in the saddle. */
export interface SaddleRide {
  ride_id: number;
  date: string | null;
  horse_id: number;
  horse: string;
  rider: string;
  gait: "walk" | "sitting_trot" | "rising_trot" | "canter";
  /** why it is too uncertain for a decision (None: it is not) */
  uncertain_reason: string | null;
  indicators: Record<string, number | null>;
}

export type SaddleSort = "id" | "-id" | "name" | "-name" | "maker" | "-maker" | "saddle_type" | "-saddle_type" | "created_at" | "-created_at";

/** One saddle on the horse: its rides and each indicator's mean with its interval. */
export interface SaddleStats {
  saddle_id: number;
  saddle: string;
  rides: number;
  indicators: Record<string, MeanWithInterval>;
}

/** What kind of saddle it is, as a saddle fitter names it. */
export type SaddleType = "gp" | "dressage" | "jump" | "treeless" | "endurance" | "western" | "other";

/**
 * Changes to a saddle (unset fields stay; null clears maker, type, tree width or notes).
 * PATCH /api/saddles/{saddle_id} takes it
 */
export interface SaddleUpdate {
  name?: string | null;
  maker?: string | null;
  saddle_type?: SaddleType | null;
  tree_width?: string | null;
  notes?: string | null;
}

/**
 * A new link with its path: shown this once (only its hash is stored), to copy for the vet.
 * POST /api/share-links answers it
 */
export interface ShareLinkCreated {
  id: number;
  kind: "ride" | "horse";
  ride_id: number | null;
  horse_id: number | null;
  /** what the link shows, in words */
  shows: string;
  /** the member who made it */
  created_by: string;
  created_at: string;
  expires_at: string;
  /** when an admin withdrew it (None: not withdrawn) */
  revoked_at: string | null;
  state: "active" | "expired" | "withdrawn";
  /** the link's path on this server: /shared/<token> */
  path: string;
}

/**
 * A read-only link to one ride's report or one horse's page, for someone without an account.
 * POST /api/share-links takes it
 */
export interface ShareLinkIn {
  /** the ride whose report the link shows */
  ride_id?: number | null;
  /** the horse whose page the link shows */
  horse_id?: number | null;
  /** how many days the link works */
  days?: number;
}

/**
 * A share link as the club's list shows it (never its token).
 * GET /api/share-links answers it
 * POST /api/share-links/{link_id}/revoke answers it
 */
export interface ShareLinkOut {
  id: number;
  kind: "ride" | "horse";
  ride_id: number | null;
  horse_id: number | null;
  /** what the link shows, in words */
  shows: string;
  /** the member who made it */
  created_by: string;
  created_at: string;
  expires_at: string;
  /** when an admin withdrew it (None: not withdrawn) */
  revoked_at: string | null;
  state: "active" | "expired" | "withdrawn";
}

/**
 * Two rides compared.
 * GET /api/rides/{ride_id}/similar/{other_id} answers it
 * (the schema saddlescope__api__similarity_schemas__PairOut)
 */
export interface SimilarityPairOut {
  rides: RideSummary[];
  markers: "saddle" | "M1" | "M2" | "M3" | "all";
  span: "stride" | "window";
  /** served from the cache (else computed for this request) */
  cached: boolean;
  /** 1 = the same motion; null when not comparable */
  similarity: number | null;
  measure: string | null;
  measures: Record<string, unknown>;
  /** why the rides could not be compared */
  reason: string | null;
  /** the similarity method's whole answer */
  comparison: Record<string, unknown>;
  /** where the motions differ; null when not comparable or cached by an older method */
  differences?: Differences | null;
  method_version: string;
  view: PairView;
}

/** S's vertical acceleration as harmonics of the stride frequency f0 (bars at k·f0), m/s² amplitudes. */
export interface SpectrumOut {
  f0_hz: number;
  frequency_hz: number[];
  amplitude_m_s2: (number | null)[];
  amplitude_wb_m_s2: (number | null)[];
  amplitude_wk_m_s2: (number | null)[];
}

/** The smallest square a camera resolves at a distance. */
export interface SquareAtDistance {
  distance_m: number;
  square_mm: number;
}

/**
 * A streamed upload has no parts: its bytes arrive through the API (resume from `offset_bytes`).
 * GET /api/uploads/{upload_id}/parts answers it
 */
export interface StreamedPartsOut {
  transport: "stream";
  /** always empty */
  parts: PartOut[];
  offset_bytes: number;
}

/** Both rides' mean strides over stride phase (mm), the second shifted to line up with the first. */
export interface StridesView {
  phase: number[];
  first_mm: number[][];
  second_mm: number[][];
  second_unaligned_mm: number[][];
  /** phase shift applied to the second stride (0-1) */
  shift_phase: number;
}

/** ride.json's "sync": the flash (default), the markers' motion, or known frame offsets per clip kind and camera. */
export interface SyncIn {
  method?: "flash" | "motion" | "offsets";
  offsets?: Partial<Record<"calibration" | "plumb" | "static" | "motion", Partial<Record<"left" | "middle" | "right", number>>>> | null;
}

/**
 * A signed-in session: the bearer token (also set as a cookie) and the CSRF token to send with it.
 * POST /api/auth/login answers it
 */
export interface TokenOut {
  access_token: string;
  token_type?: "bearer";
  /** seconds until the token (and the session cookie) expire */
  expires_in: number;
  /** the value to send as X-CSRF-Token with the session cookie */
  csrf_token: string;
  user: UserOut;
}

/**
 * One indicator of one horse in one gait over its rides, oldest first.
 * GET /api/horses/{horse_id}/trend answers it
 */
export interface TrendOut {
  horse_id: number;
  horse: string;
  gait: "walk" | "sitting_trot" | "rising_trot" | "canter";
  indicator: string;
  unit: string;
  label: string;
  min_rides_for_band: number;
  /** rides too uncertain for a decision, not shown */
  uncertain_left_out?: number;
  /** rides the horse needs for the page's band to be its own */
  min_own_rides: number;
  /** the band drawn across the chart (None: too few rides anywhere) */
  band: PageBand | null;
  points: TrendPoint[];
}

/** One analysed ride on the trend, with the band of the rides before it. */
export interface TrendPoint {
  ride_id: number;
  /** the day ridden (None: not recorded) */
  date: string | null;
  rider: string;
  value: number | null;
  /** None while the horse has fewer earlier rides than the minimum */
  band: Band | null;
  /** the value lies outside the band (None: no band) */
  outside: boolean | null;
  /** why the ride is too uncertain for a decision (only with include_uncertain; None: it is not) */
  uncertain_reason?: string | null;
}

/** A ride too uncertain for a decision (docs/accuracy.md); ``included``: counted in the ranking. */
export interface UncertainRide {
  ride_id: number;
  horse_id: number | null;
  horse: string;
  value: number | null;
  reason: string;
  included: boolean;
}

/**
 * A resumable upload to start: what the file is for and how big it is.
 * POST /api/uploads takes it
 */
export interface UploadCreate {
  target: "ride_clip" | "rig_clip" | "bundle";
  /** the file's total size */
  length_bytes: number;
  ride_id?: number | null;
  /** the rig (rig_clip), or the rig a bundle's ride uses */
  rig_id?: number | null;
  clip_kind?: "calibration" | "plumb" | "static" | "motion" | null;
  camera?: "left" | "middle" | "right" | null;
  filename?: string | null;
}

/**
 * A new upload, and how to send its bytes.
 *
 * ``stream``: PATCH chunks to the API; ``s3-parts``: PUT parts of `part_bytes` straight to the bucket,
 * to the URLs from ``POST /uploads/{id}/parts``.
 * POST /api/uploads answers it
 */
export interface UploadCreatedOut {
  id: string;
  target: string;
  ride_id: number | null;
  rig_id: number | null;
  clip_kind: string | null;
  camera_role: string | null;
  filename: string | null;
  length_bytes: number;
  offset_bytes: number;
  status: string;
  error: string | null;
  /** what finalising made (the same answer as the finalise); null until the upload is finalised */
  outcome: ClipFinalisedOut | BundleFinalisedOut | null;
  created_at: string;
  updated_at: string;
  transport?: "stream" | "s3-parts";
  part_bytes?: number | null;
  parts_total?: number | null;
}

/**
 * A resumable upload's state (`offset_bytes` is where to resume).
 * GET /api/uploads/{upload_id} answers it
 */
export interface UploadOut {
  id: string;
  target: string;
  ride_id: number | null;
  rig_id: number | null;
  clip_kind: string | null;
  camera_role: string | null;
  filename: string | null;
  length_bytes: number;
  offset_bytes: number;
  status: string;
  error: string | null;
  /** what finalising made (the same answer as the finalise); null until the upload is finalised */
  outcome: ClipFinalisedOut | BundleFinalisedOut | null;
  created_at: string;
  updated_at: string;
}

/**
 * A new user of the club (admins only).
 * POST /api/users takes it
 */
export interface UserCreate {
  email: string;
  password: string;
  display_name?: string;
  role?: "admin" | "member";
}

/**
 * A user of a club (an account; never its password).
 * GET /api/users/{user_id} answers it
 * PATCH /api/users/{user_id} answers it
 * POST /api/users answers it
 */
export interface UserOut {
  id: number;
  club_id: number;
  email: string;
  display_name: string;
  role: "admin" | "member";
  is_active: boolean;
  created_at: string;
}

/**
 * Changes to a user (unset fields stay).
 * PATCH /api/users/{user_id} takes it
 */
export interface UserUpdate {
  display_name?: string | null;
  role?: "admin" | "member" | null;
  is_active?: boolean | null;
  password?: string | null;
}

export interface ValidationError {
  loc: (string | number)[];
  msg: string;
  type: string;
  input?: unknown;
  ctx?: Record<string, unknown>;
}

/** The rig's wand clips checked before anyone rides: per camera where the wand's two ends went. */
export interface WandCheckOut {
  film_again: boolean;
  verdict: string;
  seconds?: number | null;
  /** camera -> the recording id checked */
  clips?: Record<string, number>;
  cameras?: Record<string, CameraCheckOut>;
}
