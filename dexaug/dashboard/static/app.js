// dexaug dashboard page: lists sessions and demos (/api/sessions), starts augmentations
// (POST /api/augment) with the settings chosen on the page (POST /api/settings), puts finished
// results on an arm (POST /api/arm), lists every result folder (/api/results) and shows the
// jobs' live progress by polling /api/jobs. No libraries.
"use strict";

const POLL_MS = 500;
const STAGES = { workspace: "AutoWS workspace", fsg: "FSG sampling", validate: "validation",
                 report: "report" };
const demos = new Map();   // key -> demo JSON from /api/sessions (its .result kept up to date)
const jobs = new Map();    // key -> newest augmentation job JSON from /api/jobs
const armJobs = new Map();   // demo key -> newest arm job JSON
const armFiles = new Map();  // demo key -> its result's arm files (catalog, then arm jobs)
const armChoice = new Map(); // demo key -> {arm, placements} last chosen on the page
let OPTIONS = { arms: [], arm_placements: 10, arm_placements_max: 200 };
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

function armFileRow(a) {
  if (a.error) return el("div", { class: "error arm-file-error", text: `${a.file}: ${a.error}` });
  const share = a.pass_share == null ? "—" : `${(100 * a.pass_share).toFixed(1)} %`;
  const failures = Object.entries(a.failures).map(([k, v]) => `${k} ${v}`).join(", ") || "none";
  return el("div", { class: "arm-result", "data-arm": a.arm },
    el("b", { text: a.arm }), ": ", el("span", { class: "arm-passed", text: String(a.passed) }),
    " of ", el("span", { class: "arm-pairs", text: String(a.pairs) }),
    " (placement, grasp) pairs held, ", el("b", { class: "arm-share", text: share }),
    ` · ${a.placements} placements · failures `,
    el("span", { class: "arm-failures", text: failures }), " · ",
    el("a", { class: "arm-file", href: a.url, text: a.file }),
    a.stale ? el("span", { class: "warning arm-stale", text: " (made from an earlier dataset)" })
      : null);
}

function armControls(d) {
  const choice = armChoice.get(d.key) ||
    { arm: OPTIONS.arms[0], placements: String(OPTIONS.arm_placements) };
  const select = el("select", { class: "arm-name" },
    ...OPTIONS.arms.map((a) => el("option", { value: a, text: a })));
  select.value = choice.arm;
  const input = el("input", { class: "arm-placements", type: "number", min: "1",
    max: String(OPTIONS.arm_placements_max), value: choice.placements });
  // the box is redrawn on every progress change: keep what the user chose
  const remember = () => armChoice.set(d.key, { arm: select.value, placements: input.value });
  select.addEventListener("change", remember);
  input.addEventListener("input", remember);
  const b = el("button", { class: "arm-run", text: "Put on arm" });
  b.addEventListener("click", () => startArmJob(d.key, select.value, Number(input.value), b));
  return el("div", { class: "arm-controls" }, el("label", {}, "arm ", select),
    el("label", {}, "placements ", input), b);
}

// the result's grasps on arms: the files made so far, a running job's progress, the control
function armBlock(d) {
  const box = el("div", { class: "arm" }, el("div", { class: "arm-title",
    text: "Grasps on an arm at a table" }));
  for (const a of armFiles.get(d.key) || []) box.append(armFileRow(a));
  const job = armJobs.get(d.key);
  if (job && (job.state === "queued" || job.state === "running")) {
    const text = job.state === "queued" ? `${job.label}: queued (one job at a time)`
      : `${job.stage || `${job.label}: starting`}: ${job.done} / ${job.total}`;
    const bar = el("progress", { max: String(Math.max(job.total, 1)), value: String(job.done) });
    box.append(el("div", { class: "arm-progress-text", text }), bar);
    return box;
  }
  if (job && job.state === "failed") {
    box.append(el("div", { class: "error arm-error", text: `Putting on the arm failed: ${job.error}` }));
  } else if (job && job.state === "done" && job.result.skipped) {
    box.append(el("div", { class: "arm-note", text: `${job.label}: ${job.result.skipped}` }));
  }
  if (OPTIONS.arms.length) box.append(armControls(d));
  else box.append(el("div", { text: "no arm configs installed (configs/arms/)" }));
  return box;
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
    box.append(armBlock(d));
  } else box.append(augmentButton(d, "Augment"));
}

// POST a job request; the queued job, or null after showing why not
async function submitJob(path, payload, button, what) {
  button.disabled = true;
  try {
    const r = await api(path, { method: "POST",
      headers: { "Content-Type": "application/json" }, body: JSON.stringify(payload) });
    const body = await r.json();
    if (!r.ok) throw new Error(body.error || `HTTP ${r.status}`);
    return body.job;
  } catch (e) {
    showMessage(`Could not start ${what}: ${e.message}`);
    button.disabled = false;
    return null;
  }
}

async function startJob(key, button) {
  const job = await submitJob("/api/augment", { demo: key }, button, "the augmentation");
  if (!job) return;
  jobs.set(key, job);
  renderStatus(key);
}

async function startArmJob(key, arm, placements, button) {
  const job = await submitJob("/api/arm", { demo: key, arm, placements }, button,
                              "putting the grasps on the arm");
  if (!job) return;
  armJobs.set(key, job);
  renderStatus(key);
}

async function loadSessions() {
  const r = await api("/api/sessions");
  const body = await r.json();
  if (!r.ok) throw new Error(body.error || `HTTP ${r.status}`);
  const o = body.options;
  OPTIONS = o;
  document.getElementById("options").textContent =
    `sessions ${o.sessions_dir} · results ${o.out_root} · n ${o.n} · validate ` +
    `${o.validate || "none"} · workers ${o.workers} · gallery ${o.gallery} · seed ${o.seed}`;
  showSettings(o.settings);
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
      armFiles.set(d.key, (d.result && d.result.arms) || []);
      box.append(demoRow(d));
    }
    root.append(box);
  }
  for (const key of demos.keys()) renderStatus(key);
  await loadResults();
  document.body.dataset.loaded = "1";
}

// the settings form: n, table mode and protocol of the augmentations queued from now on
function showSettings(st) {
  const fill = (id, values, chosen) => {
    const sel = document.getElementById(id);
    sel.replaceChildren(...values.map((v) => el("option", { value: v, text: v })));
    sel.value = chosen;
  };
  const n = document.getElementById("set-n");
  n.max = String(st.n_max);
  n.value = String(st.n);
  fill("set-table", st.tables, st.table);
  fill("set-validate", st.protocols, st.validate);
}

async function applySettings(ev) {
  ev.preventDefault();
  const body = { n: Number(document.getElementById("set-n").value),
                 table: document.getElementById("set-table").value,
                 validate: document.getElementById("set-validate").value };
  const r = await api("/api/settings", { method: "POST", body: JSON.stringify(body),
                                         headers: { "Content-Type": "application/json" } });
  const reply = await r.json();
  if (!r.ok) { showMessage(reply.error || `HTTP ${r.status}`); return; }
  showMessage("");
  await loadSessions();
}

// every result folder under the output folder, whatever made it (make demo, the CLI, jobs)
async function loadResults() {
  const r = await api("/api/results");
  const body = await r.json();
  const rows = body.results.map((x) => {
    const link = (href, text) => (href ? el("a", { href, text }) : null);
    const files = el("td", {}, link(x.report, "report"), x.report && x.viewer ? " · " : null,
                     link(x.viewer, "3D view"));
    if (x.error) {
      return el("tr", { "data-folder": x.folder }, el("td", { text: x.folder }),
                el("td", { class: "error", colspan: "6", text: x.error }), files);
    }
    const rate = x.pass_rate == null ? "—" : `${(100 * x.pass_rate).toFixed(1)} %`;
    return el("tr", { "data-folder": x.folder }, ...[x.folder, x.demo, x.object, x.hand,
              x.generated, x.passed, rate].map((v) => el("td", { text: String(v) })), files);
  });
  document.querySelector("#results tbody").replaceChildren(...rows);
}

async function poll() {
  try {
    const r = await api("/api/jobs");
    const body = await r.json();
    if (!r.ok) throw new Error(body.error || `HTTP ${r.status}`);
    for (const job of body.jobs) {          // oldest first: the newest per demo wins
      if (job.kind === "arm") {
        armJobSeen(job);
        continue;
      }
      const old = jobs.get(job.key);
      const changed = !old || JSON.stringify(old) !== JSON.stringify(job);
      jobs.set(job.key, job);
      const d = demos.get(job.key);
      if (d && job.state === "done" && job.result) d.result = job.result;
      // a new dataset: the arm files made from the one it replaced no longer describe it
      if (changed && job.state === "done" && job.result && !job.result.skipped) {
        armFiles.set(job.key, (armFiles.get(job.key) || []).map((a) => ({ ...a, stale: true })));
      }
      if (changed) renderStatus(job.key);
      if (changed && job.state === "done") loadResults().catch(() => {});
    }
    if (document.getElementById("message").textContent.startsWith("Lost")) showMessage("");
  } catch (e) {
    showMessage(`Lost the dashboard server (${e.message}); retrying…`);
  }
  setTimeout(poll, POLL_MS);
}

// an arm job from /api/jobs: the newest per demo is shown (several arms may be queued)
function armJobSeen(job) {
  const old = armJobs.get(job.demo);
  if (old && (old.id > job.id || JSON.stringify(old) === JSON.stringify(job))) return;
  armJobs.set(job.demo, job);
  if (job.state === "done" && job.result) armFiles.set(job.demo, job.result.arms);
  renderStatus(job.demo);
}

document.getElementById("settings").addEventListener("submit", (ev) =>
  applySettings(ev).catch((e) => showMessage(`Could not change the settings: ${e.message}`)));
document.getElementById("rescan").addEventListener("click", () =>
  loadSessions().catch((e) => showMessage(`Could not list sessions: ${e.message}`)));
loadSessions().catch((e) => showMessage(`Could not list sessions: ${e.message}`)).then(poll);
