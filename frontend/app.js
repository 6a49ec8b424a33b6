// SaddleScope dashboard: routes, the signed-in state in the header, and start-up.

import { messageOf, one, page } from "./js/dom.js";
import { loadConstants } from "./js/glossary.js";
import { checkHealth } from "./js/health.js";
import { currentPath, navigate, render, route } from "./js/router.js";
import { onSessionChange, refreshSession, session, signOut } from "./js/session.js";

/**
 * A page's module, loaded on its first visit (start-up fetches only the shell, not every page's code):
 * `mountX` of the module, or `mountX(...args)` for pages made by a factory. The router starts `load`
 * beside the page's markup (each route's `markup`: the .html files beside the modules that use them).
 * @template {Record<string, unknown>} M
 * @param {() => Promise<M>} load
 * @param {keyof M & string} name
 * @param {...string} args
 * @returns {import("./js/router.js").Mount}
 */
function lazy(load, name, ...args) {
  /** @type {import("./js/router.js").Mount} */
  const mountLazily = async (view, params, query) => {
    // `name` is a mount of the module, or (with args) a factory of one
    const mount = /** @type {Function} */ ((await load())[name]);
    return /** @type {import("./js/router.js").Mount} */ (args.length ? mount(...args) : mount)(view, params, query);
  };
  return Object.assign(mountLazily, { load });
}

route("/", lazy(() => import("./js/views/home.js"), "mountHome"),
      { title: "Overview", markup: ["js/views/home.html"] });
route("/start", lazy(() => import("./js/views/start.js"), "mountStart"),
      { title: "Getting started", markup: ["js/views/start.html"] });
route("/login", lazy(() => import("./js/views/login.js"), "mountLogin"),
      { title: "Sign in", auth: false, markup: ["js/views/login.html"] });
route("/horses", lazy(() => import("./js/views/entities.js"), "mountEntities", "horses"),
      { title: "Horses", markup: ["js/views/entities.html"] });
route("/horses/:id", lazy(() => import("./js/views/horse.js"), "mountHorse"),
      { title: "Horse", markup: ["js/views/horse.html"] });
route("/riders", lazy(() => import("./js/views/entities.js"), "mountEntities", "riders"),
      { title: "Riders", markup: ["js/views/entities.html"] });
route("/saddles", lazy(() => import("./js/views/entities.js"), "mountEntities", "saddles"),
      { title: "Saddles", markup: ["js/views/entities.html"] });
route("/saddles/:id", lazy(() => import("./js/views/saddle.js"), "mountSaddle"),
      { title: "Saddle", markup: ["js/views/saddle.html"] });
route("/rides", lazy(() => import("./js/views/rides.js"), "mountRides"),
      { title: "Rides", markup: ["js/views/rides.html", "js/ride-edit.html"] });
route("/rides/:id", lazy(() => import("./js/views/ride.js"), "mountRide"),
      { title: "Ride", markup: ["js/views/ride.html", "js/ride-edit.html"] });
route("/compare-rides/:a/:b", lazy(() => import("./js/views/similar.js"), "mountRidePair"),
      { title: "Two rides compared", markup: ["js/views/similar.html"] });
route("/upload", lazy(() => import("./js/views/upload.js"), "mountUpload"),
      { title: "Upload a ride", markup: ["js/views/upload.html"] });
route("/rigs", lazy(() => import("./js/views/rigs.js"), "mountRigs"),
      { title: "Rigs", markup: ["js/views/rigs.html"] });
route("/rigs/:id", lazy(() => import("./js/views/rigs.js"), "mountRig"),
      { title: "Rig", markup: ["js/views/rigs.html"] });
route("/jobs", lazy(() => import("./js/views/jobs.js"), "mountJobs"),
      { title: "Jobs", markup: ["js/views/jobs.html"] });
route("/compare", lazy(() => import("./js/views/compare.js"), "mountCompare"),
      { title: "Compare", markup: ["js/views/compare.html"] });
route("/leaderboard", lazy(() => import("./js/views/leaderboard.js"), "mountLeaderboard"),
      { title: "Leaderboard", markup: ["js/views/leaderboard.html"] });
route("/grades", lazy(() => import("./js/views/grades.js"), "mountGrades"),
      { title: "Grades", markup: ["js/views/grades.html"] });
route("/account", lazy(() => import("./js/views/account.js"), "mountAccount"),
      { title: "Your account", markup: ["js/views/account.html"] });
route("/reset-password", lazy(() => import("./js/views/reset-password.js"), "mountResetPassword"),
      { title: "Set a new password", auth: false, markup: ["js/views/reset-password.html"] });

const view = one(document, "[data-view]");

/**
 * @param {import("./js/router.js").Route} target
 * @param {string} path
 */
function guard(target, path) {
  if (target.auth && !session()) return `/login?next=${encodeURIComponent(path)}`;
  return null;
}

/** @param {HTMLElement} el */
function notFound(el) {
  el.append(page("not-found"));
}

// Pages anyone may open: a session ending there does not send the user to sign in.
const OPEN_PAGES = new Set(["/login", "/reset-password"]);

/** @param {import("./js/api-types").MeOut | null} current */
function showAccount(current) {
  const name = one(document, "[data-account-name]");
  const login = one(document, "[data-account-login]");
  const logout = one(document, "[data-account-logout]");
  name.textContent = current ? `${current.user.display_name || current.user.email}${current.club ? ` \u00b7 ${current.club.name}` : ""}` : "";
  name.hidden = !current;
  login.hidden = Boolean(current);
  logout.hidden = !current;
  one(document, "[data-nav]").hidden = !current;
  one(document, "[data-nav-toggle]").hidden = !current;
  one(document, ".site-header").toggleAttribute("data-signed-in", Boolean(current));
}

/** The phone menu: the button folds the nav and the account links open and shut (Escape shuts it). */
function setUpMenu() {
  const header = one(document, ".site-header");
  const toggle = one(header, "[data-nav-toggle]");
  const setOpen = (/** @type {boolean} */ open) => {
    header.toggleAttribute("data-nav-open", open);
    toggle.setAttribute("aria-expanded", String(open));
  };
  toggle.addEventListener("click", () => setOpen(!header.hasAttribute("data-nav-open")));
  header.addEventListener("keydown", (event) => {
    if (event.key === "Escape" && header.hasAttribute("data-nav-open")) {
      setOpen(false);
      toggle.focus();
    }
  });
  window.addEventListener("hashchange", () => setOpen(false)); // a link was followed
}

/**
 * The server did not answer the start-up's constants: say so (no page is drawn with guessed labels).
 * @param {unknown} error
 */
function showUnreachable(error) {
  const unreachable = page("unreachable");
  one(unreachable, "[data-unreachable-reason]").textContent = messageOf(error);
  one(unreachable, "[data-unreachable-retry]").addEventListener("click", () => window.location.reload());
  view.replaceChildren(unreachable);
  document.title = "Cannot reach the server \u2013 SaddleScope";
}

async function start() {
  one(document, "[data-account-logout]").addEventListener("click", async () => {
    await signOut();
    navigate("/login");
  });
  setUpMenu();
  /** @type {import("./js/api-types").MeOut | null} */
  let previous = null;
  onSessionChange((current) => {
    showAccount(current);
    // Signed out (or the session expired) while on a page that needs it: back to sign-in.
    if (previous && !current && !OPEN_PAGES.has(currentPath().path)) {
      navigate(`/login?next=${encodeURIComponent(currentPath().path)}`);
    }
    previous = current;
    // signed in: the chart library comes into the cache while nothing else is asked for
    if (current) {
      (window.requestIdleCallback ?? ((/** @type {() => void} */ work) => setTimeout(work, 2000)))(
        () => import("./js/charts.js").then((charts) => charts.prefetchPlotly()));
    }
  });
  checkHealth();
  // the server's constants (labels of every code, the indicator table; open without sign-in), asked
  // for beside the session and in hand before the first page is drawn
  // (its failure held as a value: a rejection waiting for the session would count as unhandled)
  const constantsFailed = loadConstants().then(() => null, (error) => error);
  try {
    await refreshSession();
  } catch (error) {
    console.warn("cannot ask who is signed in:", messageOf(error));
  }
  const failed = await constantsFailed;
  if (failed) {
    showUnreachable(failed);
    return;
  }
  window.addEventListener("hashchange", () => render());
  await render({ view, guard, notFound });
}

start();
