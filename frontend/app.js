// SaddleScope dashboard: routes, the signed-in state in the header, and start-up.

import { page } from "./js/dom.js";
import { loadConstants } from "./js/glossary.js";
import { checkHealth } from "./js/health.js";
import { currentPath, navigate, render, route } from "./js/router.js";
import { onSessionChange, refreshSession, session, signOut } from "./js/session.js";

/**
 * A page's module, loaded on its first visit (start-up fetches only the shell, not every page's code):
 * `mountX` of the module, or `mountX(...args)` for pages made by a factory. The router starts `load`
 * beside the page's markup (each route's `markup`: the .html files beside the modules that use them).
 */
function lazy(load, name, ...args) {
  const mountLazily = async (view, params, query) => {
    const mount = (await load())[name];
    return (args.length ? mount(...args) : mount)(view, params, query);
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

const view = document.querySelector("[data-view]");

function guard(target, path) {
  if (target.auth && !session()) return `/login?next=${encodeURIComponent(path)}`;
  return null;
}

function notFound(el) {
  el.append(page("not-found"));
}

// Pages anyone may open: a session ending there does not send the user to sign in.
const OPEN_PAGES = new Set(["/login", "/reset-password"]);

function showAccount(current) {
  const name = document.querySelector("[data-account-name]");
  const login = document.querySelector("[data-account-login]");
  const logout = document.querySelector("[data-account-logout]");
  name.textContent = current ? `${current.user.display_name || current.user.email}${current.club ? ` \u00b7 ${current.club.name}` : ""}` : "";
  name.hidden = !current;
  login.hidden = Boolean(current);
  logout.hidden = !current;
  document.querySelector("[data-nav]").hidden = !current;
  document.querySelector("[data-nav-toggle]").hidden = !current;
  document.querySelector(".site-header").toggleAttribute("data-signed-in", Boolean(current));
}

/** The phone menu: the button folds the nav and the account links open and shut (Escape shuts it). */
function setUpMenu() {
  const header = document.querySelector(".site-header");
  const toggle = header.querySelector("[data-nav-toggle]");
  const setOpen = (open) => {
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

/** The server did not answer the start-up's constants: say so (no page is drawn with guessed labels). */
function showUnreachable(error) {
  const unreachable = page("unreachable");
  unreachable.querySelector("[data-unreachable-reason]").textContent = error.message;
  unreachable.querySelector("[data-unreachable-retry]").addEventListener("click", () => window.location.reload());
  view.replaceChildren(unreachable);
  document.title = "Cannot reach the server \u2013 SaddleScope";
}

async function start() {
  document.querySelector("[data-account-logout]").addEventListener("click", async () => {
    await signOut();
    navigate("/login");
  });
  setUpMenu();
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
      (window.requestIdleCallback ?? ((work) => setTimeout(work, 2000)))(
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
    console.warn("cannot ask who is signed in:", error.message);
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
