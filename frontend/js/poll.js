// Repeat `work` every `intervalMs` while it resolves to true (or to a number: wait that many ms);
// false stops. Pauses while the tab is hidden and resumes when it is shown again.

/**
 * @typedef {object} Poller
 * @property {() => void} now run `work` at once (and go on from there)
 * @property {() => void} restart after `work` said stop (false): start polling again, e.g. when a job is retried
 * @property {() => void} stop
 */

/**
 * @param {() => Promise<boolean | number> | boolean | number} work true: again after `intervalMs`; a number:
 *   again after that many ms; false: stop
 * @param {{intervalMs?: number}} [options]
 * @returns {Poller}
 */
export function poll(work, { intervalMs = 1500 } = {}) {
  /** @type {number | null} */
  let timer = null;
  let stopped = false;
  let running = false;

  async function tick() {
    timer = null;
    if (stopped || running) return;
    running = true;
    /** @type {boolean | number} */
    let again = false;
    try {
      again = await work();
    } finally {
      running = false;
    }
    if (again && !stopped && !document.hidden) {
      timer = window.setTimeout(tick, typeof again === "number" ? again : intervalMs);
    }
  }

  function onVisibility() {
    if (!document.hidden && !timer && !stopped) tick();
  }

  document.addEventListener("visibilitychange", onVisibility);
  tick();
  return {
    now: () => { if (timer) window.clearTimeout(timer); tick(); },
    // After `work` said stop (false): start polling again, e.g. when a job is retried.
    restart: () => { if (timer) window.clearTimeout(timer); timer = null; stopped = false; tick(); },
    stop: () => {
      stopped = true;
      if (timer) window.clearTimeout(timer);
      document.removeEventListener("visibilitychange", onVisibility);
    },
  };
}
