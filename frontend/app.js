// SaddleScope placeholder dashboard: asks /api/health and shows each part (the real dashboard comes later).

const summary = document.querySelector("[data-health-summary]");
const table = document.querySelector("[data-health-table]");
const refresh = document.querySelector("[data-health-refresh]");

function row(name, part) {
  const tr = document.createElement("tr");
  tr.dataset.part = name;
  for (const [text, cls] of [[name, ""], [part.ok ? "ok" : "error", part.ok ? "ok" : "error"], [part.detail, ""]]) {
    const td = document.createElement("td");
    td.textContent = text;
    if (cls) td.className = cls;
    tr.append(td);
  }
  return tr;
}

export async function checkHealth() {
  summary.textContent = "Checking\u2026";
  try {
    const response = await fetch("/api/health", { headers: { Accept: "application/json" } });
    const health = await response.json();
    const body = table.tBodies[0];
    body.replaceChildren(...Object.entries(health.parts).map(([name, part]) => row(name, part)));
    table.hidden = false;
    summary.textContent = `SaddleScope ${health.version} (${health.mode} mode): ` +
      (health.status === "ok" ? "all parts ok" : "some parts are not ok");
    summary.dataset.status = health.status;
  } catch (error) {
    summary.textContent = `Cannot reach the server: ${error.message}`;
    summary.dataset.status = "error";
  }
}

refresh.addEventListener("click", checkHealth);
checkHealth();
