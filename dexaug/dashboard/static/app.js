// dexaug dashboard page: lists sessions and demos (/api/sessions), starts augmentations
// (POST /api/augment) and shows their live progress by polling /api/jobs. No libraries.
"use strict";

const POLL_MS = 500;
const STAGES = { workspace: "AutoWS workspace", fsg: "FSG sampling", validate: "validation",
                 report: "report" };
const demos = new Map();   // key -> demo JSON from /api/sessions (its .result kept up to date)
const jobs = new Map();    // key -> newest job JSON from /api/jobs
// Every request carries the custom header the server requires of the page (a cross-site page
// cannot send it without a CORS preflight, which the server never grants) and, when the page
// was opened with the printed URL's token (a dashboard listening beyond this machine), the token.
const TOKEN = new URLSearchParams(location.search).get("token");
const HEADERS = TOKEN ? { "X-Dexaug": "1", "X-Dexaug-Token": TOKEN } : { "X-Dexaug": "1" };

function api(path, init = {}) {
  return fetch(path, { ...init, headers: { ...HEADERS, ...(init.headers || {}) } });
}

function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") e.className = v; else if (k === "text") e.textContent = v;
    else e.setAttribute(k, v);
  }
  for (const c of children) if (c != null) e.append(c);
  return e;
}

function showMessage(text) {
  const m = document.getElementById("message");
  m.textContent = text || "";
  m.className = text ? "error" : "";
}

function fact(name, value) {
  return el("div", {}, el("b", { text: name }), document.createTextNode(String(value)));
}

function demoRow(d) {
  const facts = el("div", { class: "facts" },
    fact("demo", d.id), fact("object", d.object), fact("hand", d.hand),
    fact("fingers", d.fingers.join(", ") || "—"),
    fact("time", `${d.time_s.toFixed(2)} s (${d.how}, held ${d.duration_s.toFixed(2)} s)`));
  const img = el("img", { src: d.thumbnail, alt: `grasp of ${d.id}`, loading: "lazy" });
  const status = el("div", { class: "status" });
  return el("div", { class: "demo", "data-key": d.key }, img, facts, status);
}

function resultBlock(r) {
  const rate = r.pass_rate == null ? "—" : `${(100 * r.pass_rate).toFixed(1)} %`;
  const nums = el("div", { class: "numbers" },
    el("span", {}, "generated ", el("b", { class: "n-generated", text: String(r.generated) })),
    el("span", {}, "passed ", el("b", { class: "n-passed", text: String(r.passed) })),
    el("span", {}, "pass rate ", el("b", { class: "pass-rate", text: rate })));
  // the demo's own grasp under the same protocol: a low pass rate reads differently when the
  // grasp it was augmented from does not hold either
  const verdict = r.demo_grasp == null ? "" : r.demo_grasp.passed ? "ok" : "bad";
  const demoGrasp = el("div", {}, "demonstration grasp: ",
    el("b", { class: `demo-grasp ${verdict}`, text: r.demo_grasp_text }));
  const failures = Object.entries(r.failures || {}).map(([k, v]) => `${k} ${v}`).join(", ");
  const link = r.report_url
    ? el("a", { class: "report-link", href: r.report_url, target: "_blank", text: "report" })
    : el("span", { text: "no report (gallery 0)" });
  const note = r.earlier
    ? `Augmented earlier with other options (${r.requested} grasps asked for, e.g. by make demo); ` +
      "augmenting again uses the dashboard's and replaces it."
    : r.skipped ? "Augmented earlier with these options." : "Augmentation finished.";
  return el("div", {}, el("div", { class: r.earlier ? "done-note earlier" : "done-note",
    text: note }),
    nums, demoGrasp, failures ? el("div", { text: `failures: ${failures}` }) : null, link);
}

function augmentButton(d, label) {
  const b = el("button", { class: "augment", text: label });
  b.addEventListener("click", () => startJob(d.key, b));
  return b;
}

function renderStatus(key) {
  const d = demos.get(key);
  const box = document.querySelector(`.demo[data-key="${CSS.escape(key)}"] .status`);
  if (!d || !box) return;
  const job = jobs.get(key);
  box.replaceChildren();
  if (d.error) {
    box.append(el("div", { class: "error demo-error", text: d.error }));
    return;
  }
  if (job && (job.state === "queued" || job.state === "running")) {
    const stage = STAGES[job.stage] || job.stage || "starting";
    const text = job.state === "queued" ? "queued (one augmentation at a time)"
      : `${stage}: ${job.done} / ${job.total}`;
    const bar = el("progress", { max: String(Math.max(job.total, 1)), value: String(job.done) });
    box.append(el("div", { class: "progress-text", text }), bar);
    return;
  }
  if (job && job.state === "failed") {
    box.append(el("div", { class: "error job-error", text: `Augmentation failed: ${job.error}` }),
               augmentButton(d, "Retry"));
    return;
  }
  if (d.result) {
    box.append(resultBlock(d.result));
    if (d.result.earlier) box.append(augmentButton(d, "Augment with the dashboard's options"));
  } else box.append(augmentButton(d, "Augment"));
}

async function startJob(key, button) {
  button.disabled = true;
  try {
    const r = await api("/api/augment", { method: "POST",
      headers: { "Content-Type": "application/json" }, body: JSON.stringify({ demo: key }) });
    const body = await r.json();
    if (!r.ok) throw new Error(body.error || `HTTP ${r.status}`);
    jobs.set(key, body.job);
    renderStatus(key);
  } catch (e) {
    showMessage(`Could not start the augmentation: ${e.message}`);
    button.disabled = false;
  }
}

async function loadSessions() {
  const r = await api("/api/sessions");
  const body = await r.json();
  if (!r.ok) throw new Error(body.error || `HTTP ${r.status}`);
  const o = body.options;
  document.getElementById("options").textContent =
    `sessions ${o.sessions_dir} · results ${o.out_root} · n ${o.n} · validate ` +
    `${o.validate || "none"} · workers ${o.workers} · gallery ${o.gallery} · seed ${o.seed}`;
  showMessage(body.error);
  const root = document.getElementById("sessions");
  root.replaceChildren();
  demos.clear();
  if (!body.sessions.length && !body.error) root.append(el("p", { text: "No *.mcap sessions." }));
  for (const s of body.sessions) {
    const box = el("div", { class: "session", "data-session": s.name },
                   el("h2", { text: s.name }));
    if (s.error) box.append(el("div", { class: "error session-error", text: s.error }));
    if (s.warning) box.append(el("div", { class: "warning session-warning", text: s.warning }));
    for (const d of s.demos) {
      demos.set(d.key, d);
      box.append(demoRow(d));
    }
    root.append(box);
  }
  for (const key of demos.keys()) renderStatus(key);
  document.body.dataset.loaded = "1";
}

async function poll() {
  try {
    const r = await api("/api/jobs");
    const body = await r.json();
    if (!r.ok) throw new Error(body.error || `HTTP ${r.status}`);
    for (const job of body.jobs) {          // oldest first: the newest per demo wins
      const old = jobs.get(job.key);
      const changed = !old || JSON.stringify(old) !== JSON.stringify(job);
      jobs.set(job.key, job);
      const d = demos.get(job.key);
      if (d && job.state === "done" && job.result) d.result = job.result;
      if (changed) renderStatus(job.key);
    }
    if (document.getElementById("message").textContent.startsWith("Lost")) showMessage("");
  } catch (e) {
    showMessage(`Lost the dashboard server (${e.message}); retrying…`);
  }
  setTimeout(poll, POLL_MS);
}

document.getElementById("rescan").addEventListener("click", () =>
  loadSessions().catch((e) => showMessage(`Could not list sessions: ${e.message}`)));
loadSessions().catch((e) => showMessage(`Could not list sessions: ${e.message}`)).then(poll);
