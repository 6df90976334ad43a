// The lightfarm dashboard: renders the view its path names from the coordinator's JSON API
// (/api/v1/) and refreshes it every second. Everything users typed (job names, scene paths,
// errors) reaches the page through textContent, never as HTML.
"use strict";

const REFRESH_MS = 1000;
const TERMINAL = new Set(["done", "failed", "cancelled"]);

// --- small DOM helpers -----------------------------------------------------------------------------

// Replaces a node's children with the given ones, skipping null (optional parts of a view).
function show(node, ...children) {
  node.replaceChildren(...children.filter((c) => c !== null && c !== undefined));
}

// el("td", {class: "num"}, "text", child, ...): strings become text nodes.
function el(tag, attrs, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else node.setAttribute(k, v === true ? "" : String(v));
  }
  for (const c of children) {
    if (c === undefined || c === null) continue;
    node.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return node;
}

function svg(tag, attrs, text) {
  const node = document.createElementNS("http://www.w3.org/2000/svg", tag);
  for (const [k, v] of Object.entries(attrs || {})) node.setAttribute(k, String(v));
  if (text !== undefined) node.textContent = text;
  return node;
}

function seconds(s) {
  if (s === undefined || s === null || s < 0) return "—";
  if (s < 60) return s.toFixed(1) + " s";
  if (s < 3600) return Math.floor(s / 60) + " min " + Math.round(s % 60) + " s";
  return Math.floor(s / 3600) + " h " + Math.round((s % 3600) / 60) + " min";
}

function bar(fraction) {
  const f = Math.max(0, Math.min(1, fraction || 0));
  const inner = el("span");
  inner.style.width = (100 * f).toFixed(1) + "%";
  return el("span", {class: "bar", role: "progressbar", "aria-valuenow": Math.round(100 * f)}, inner);
}

// Progress as text: passes and noise for progressive jobs, the stage's tasks otherwise.
function progressText(j) {
  const parts = [];
  if (j.progressive) {
    parts.push("pass " + Math.min(j.passes_done + (TERMINAL.has(j.state) ? 0 : 1), j.passes_total) +
               "/" + j.passes_total);
    if (j.noise_rel_stderr >= 0)
      parts.push("noise " + (100 * j.noise_rel_stderr).toFixed(2) + "% (p90 pixel " +
                 (100 * j.noise_p90_rel_stderr).toFixed(1) + "%)");
  }
  if (!TERMINAL.has(j.state) && j.tasks_total > 0)
    parts.push("stage " + (j.stage + 1) + "/" + j.stage_count + " " + j.stage_name + ": " +
               j.tasks_done + "/" + j.tasks_total + " tasks");
  return parts.join(", ");
}

function progressFraction(j) {
  if (j.state === "done") return 1;
  if (j.progressive && j.passes_total > 0 && j.passes_total < 10000) {
    const inPass = !TERMINAL.has(j.state) && j.tasks_total > 0 ? j.tasks_done / j.tasks_total : 0;
    return (j.passes_done + inPass) / j.passes_total;
  }
  if (j.tasks_total > 0) return (j.stage + j.tasks_done / j.tasks_total) / Math.max(1, j.stage_count);
  return 0;
}

async function api(path, options) {
  const response = await fetch(path, Object.assign({credentials: "same-origin"}, options || {}));
  if (response.status === 401) {
    window.location.href = "/login";
    throw new Error("not logged in");
  }
  const body = response.headers.get("content-type")?.includes("json") ? await response.json() : null;
  if (!response.ok) throw new Error((body && body.error) || response.status + " " + response.statusText);
  return body;
}

function post(path, body) {
  return api(path, {method: "POST", headers: {"X-Lightfarm-Request": "1", "Content-Type": "application/json"},
                    body: JSON.stringify(body || {})});
}

function setStatus(text, isError) {
  const line = document.getElementById("status-line");
  line.textContent = text;
  line.className = isError ? "error" : "muted";
}

function stateCell(state) {
  return el("td", {class: "state state-" + state}, state);
}

function cancelButton(j, after) {
  if (TERMINAL.has(j.state)) return null;
  return el("button", {class: "cancel", "data-job-id": j.id, onclick: async (e) => {
    e.preventDefault();
    try {
      await post("/api/v1/jobs/" + j.id + "/cancel");
      setStatus("job " + j.id + " cancelled");
    } catch (err) {
      setStatus("cancel job " + j.id + ": " + err.message, true);
    }
    after();
  }}, "Cancel");
}

function deleteButton(j, after) {
  if (!TERMINAL.has(j.state)) return null;
  return el("button", {class: "delete", "data-job-id": j.id, onclick: async (e) => {
    e.preventDefault();
    try {
      await post("/api/v1/jobs/" + j.id + "/delete");
      setStatus("job " + j.id + " deleted");
    } catch (err) {
      setStatus("delete job " + j.id + ": " + err.message, true);
    }
    after();
  }}, "Delete");
}

// --- views -------------------------------------------------------------------------------------------

async function jobsView(view) {
  const {jobs} = await api("/api/v1/jobs");
  const rows = jobs.map((j) => el("tr", {"data-job-id": j.id, "data-state": j.state},
    el("td", {class: "num"}, el("a", {href: "/jobs/" + j.id}, j.id)),
    el("td", {class: "name"}, j.name),
    el("td", {}, j.scene),
    stateCell(j.state),
    el("td", {}, j.method),
    el("td", {class: "num"}, j.priority),
    el("td", {}, bar(progressFraction(j)), progressText(j)),
    el("td", {class: "num"}, seconds(j.elapsed_s)),
    el("td", {class: "num"}, TERMINAL.has(j.state) ? "—" : seconds(j.eta_s)),
    el("td", {class: "num"}, j.attempts),
    el("td", {}, cancelButton(j, refresh), deleteButton(j, refresh))));
  show(view, 
    el("h1", {}, "Jobs"),
    jobs.length === 0 ? el("p", {class: "muted"}, "No jobs yet: submit one with `lightfarm submit`.") :
    el("table", {id: "jobs"},
      el("thead", {}, el("tr", {}, ...["Job", "Name", "Scene", "State", "Method", "Priority", "Progress",
                                      "Elapsed", "ETA", "Attempts", ""].map((h) => el("th", {}, h)))),
      el("tbody", {}, ...rows)));
}

// Stats JSON flattened to dotted keys, one table row each.
function flatten(value, prefix, out) {
  if (value !== null && typeof value === "object" && !Array.isArray(value)) {
    for (const [k, v] of Object.entries(value)) flatten(v, prefix ? prefix + "." + k : k, out);
  } else {
    out.push([prefix, Array.isArray(value) ? JSON.stringify(value) : String(value)]);
  }
  return out;
}

const jobPage = {id: null, previewVersion: null, previewUrl: null, bench: null};

async function jobView(view, id) {
  const j = await api("/api/v1/jobs/" + id);
  if (jobPage.id !== id) Object.assign(jobPage, {id: id, previewVersion: null, previewUrl: null});
  const fields = [
    ["State", el("span", {id: "job-state", class: "state-" + j.state}, j.state)],
    ["Scene", j.scene], ["Method", j.method],
    ["Progress", el("span", {id: "job-progress"}, bar(progressFraction(j)), progressText(j))],
    ["Elapsed", seconds(j.elapsed_s)], ["ETA", TERMINAL.has(j.state) ? "—" : seconds(j.eta_s)],
    ["Attempts", j.attempts + " (" + j.tasks_completed_total + " tasks completed)"],
  ];
  const info = el("table", {id: "job-info"}, ...fields.map(([k, v]) => el("tr", {}, el("th", {}, k), el("td", {}, v))));

  const controls = el("p", {class: "controls"});
  if (!TERMINAL.has(j.state)) {
    const input = el("input", {type: "number", id: "priority-input", value: j.priority, step: 1});
    controls.append("Priority ", input, " ",
      el("button", {id: "priority-set", onclick: async () => {
        try {
          await post("/api/v1/jobs/" + id + "/priority", {priority: parseInt(input.value, 10)});
          setStatus("job " + id + ": priority " + input.value);
        } catch (err) {
          setStatus("priority: " + err.message, true);
        }
        refresh();
      }}, "Set"), " ", cancelButton(j, refresh));
  } else {
    controls.append("Priority " + j.priority);
  }

  // The image: a live preview while it renders, the result once there is one.
  const image = el("div", {class: "image"});
  if (j.has_result) {
    image.append(el("h2", {}, j.state === "done" ? "Result" : "Mean of the finished passes"),
                 el("img", {id: "final-image", class: "final", alt: "result of job " + id,
                            src: "/api/v1/jobs/" + id + "/image.png?p=" + (j.passes_done || 0)}),
                 el("p", {}, el("a", {id: "download-exr", href: "/api/v1/jobs/" + id + "/result.exr",
                                      download: "lightfarm-job-" + id + ".exr"}, "Download EXR")));
  }
  if (!TERMINAL.has(j.state)) {
    const version = j.stage + ":" + j.tasks_done + ":" + (j.passes_done || 0);
    if (version !== jobPage.previewVersion) {
      jobPage.previewVersion = version;
      try {
        const r = await fetch("/api/v1/jobs/" + id + "/preview.png", {credentials: "same-origin"});
        if (r.ok) {
          if (jobPage.previewUrl) URL.revokeObjectURL(jobPage.previewUrl);
          jobPage.previewUrl = URL.createObjectURL(await r.blob());
        }
      } catch (err) { /* the next refresh tries again */ }
    }
    image.prepend(el("h2", {}, "Preview"), jobPage.previewUrl ?
      el("img", {id: "preview", alt: "preview of job " + id, src: jobPage.previewUrl}) :
      el("p", {id: "preview-waiting", class: "muted"}, "The preview appears when the final stage's first tiles are done."));
  }

  // Per-stage progress: the stages before the current one are done, the current one has its
  // tasks, the later ones wait (a progressive job runs them all once per pass).
  const stages = el("table", {id: "stages"}, el("thead", {}, el("tr", {}, el("th", {}, "Stage"), el("th", {}, "Progress"))),
    el("tbody", {}, ...Array.from({length: Math.max(1, j.stage_count)}, (_, i) => {
      let cell;
      if (j.state === "done" || i < j.stage) cell = [bar(1), "done"];
      else if (i > j.stage || j.state === "queued" || j.state === "planning") cell = [bar(0), "waiting"];
      else if (TERMINAL.has(j.state)) cell = [bar(j.tasks_total ? j.tasks_done / j.tasks_total : 0), j.state];
      else cell = [bar(j.tasks_total ? j.tasks_done / j.tasks_total : 0), j.tasks_done + "/" + j.tasks_total + " tasks"];
      const label = (i + 1) + (i === j.stage && j.stage_name ? " " + j.stage_name : "");
      return el("tr", {"data-stage": i}, el("td", {}, label), el("td", {}, ...cell));
    })));

  const stats = j.stats ? el("table", {id: "stats"}, ...flatten(j.stats, "", []).map(([k, v]) =>
    el("tr", {}, el("th", {}, k), el("td", {}, v)))) : null;

  if (!jobPage.bench) jobPage.bench = await api("/api/v1/bench");  // once per page load
  const bench = jobPage.bench;
  const sceneKey = Object.keys(bench.scenes).find((k) => j.scene_sha256 && bench.scenes[k].sha256 === j.scene_sha256);
  const benchLink = sceneKey ?
    el("p", {}, el("a", {href: "/bench?scene=" + encodeURIComponent(sceneKey), id: "bench-link"},
                   "Error versus time of every method on " + sceneKey)) : null;

  show(view, 
    el("h1", {}, "Job " + id + " ", el("span", {id: "job-name", class: "muted"}, j.name)),
    j.error && j.state !== "cancelled" ? el("p", {id: "job-error", class: "error"}, j.error) : null,
    j.waiting ? el("p", {id: "job-waiting", class: "error"}, "Waiting: " + j.waiting) : null,
    j.tasks_verified ? el("p", {id: "job-verified", class: "muted"},
                          j.tasks_verified + " tasks verified on a second worker, bit for bit") : null,
    controls,
    el("div", {class: "cols"}, el("div", {}, info, el("h2", {}, "Stages"), stages, benchLink,
                                  stats ? el("h2", {}, "Stats") : null, stats), image));
}

async function workersView(view) {
  const {workers} = await api("/api/v1/workers");
  show(view, 
    el("h1", {}, "Workers"),
    workers.length === 0 ? el("p", {class: "muted"}, "No worker has called since this coordinator started.") :
    el("table", {id: "workers"},
      el("thead", {}, el("tr", {}, ...["Name", "Id", "Version", "Threads", "Current task", "Last heartbeat",
                                      "Tasks done", "Failed", "Kept off jobs"].map((h) => el("th", {}, h)))),
      el("tbody", {}, ...workers.map((w) => el("tr", {"data-worker-id": w.id, class: w.alive ? "" : "muted"},
        el("td", {}, w.name), el("td", {}, w.id), el("td", {}, w.version), el("td", {class: "num"}, w.threads),
        el("td", {}, w.job_id ? el("a", {href: "/jobs/" + w.job_id}, "job " + w.job_id) : "idle",
                 w.lease_id ? " (" + w.lease_id + ")" : ""),
        el("td", {class: "num"}, seconds(w.last_seen_s) + " ago" + (w.alive ? "" : " (lost)")),
        el("td", {class: "num"}, w.tasks_done), el("td", {class: "num"}, w.tasks_failed),
        el("td", {}, w.blocklisted ? el("span", {class: "error"}, "blocklisted: " + w.blocklisted + " ") : "",
                 ...w.blocked_jobs.map((b) => el("a", {href: "/jobs/" + b}, b + " "))))))));
}

// Error against time on log-log axes, one colour per method: what accuracy costs.
function benchPlot(scene, rows) {
  const W = 640, H = 380, L = 64, R = 150, T = 16, B = 44;
  const errorOf = (r) => (r.truth_rel_l1 !== null ? r.truth_rel_l1 : r.rel_l1);
  const pts = rows.filter((r) => r.time_s > 0 && errorOf(r) > 0);
  const vs = pts.some((r) => r.truth_rel_l1 !== null) ? "the truth" : "same-lights brute force";
  const plot = svg("svg", {width: W, height: H, viewBox: `0 0 ${W} ${H}`, role: "img", "data-scene": scene});
  if (pts.length === 0) {
    plot.append(svg("text", {x: 20, y: 30}, "no rows with a time and an error"));
    return plot;
  }
  const lx = pts.map((r) => Math.log10(r.time_s)), ly = pts.map((r) => Math.log10(errorOf(r)));
  const x0 = Math.floor(Math.min(...lx)), x1 = Math.max(x0 + 1, Math.ceil(Math.max(...lx)));
  const y0 = Math.floor(Math.min(...ly)), y1 = Math.max(y0 + 1, Math.ceil(Math.max(...ly)));
  const X = (v) => L + (W - L - R) * (v - x0) / (x1 - x0), Y = (v) => H - B - (H - T - B) * (v - y0) / (y1 - y0);
  for (let d = x0; d <= x1; ++d) {
    plot.append(svg("line", {x1: X(d), x2: X(d), y1: T, y2: H - B, stroke: "#e3e7eb"}),
                svg("text", {x: X(d), y: H - B + 16, "text-anchor": "middle"}, String(10 ** d) + " s"));
  }
  for (let d = y0; d <= y1; ++d) {
    plot.append(svg("line", {x1: L, x2: W - R, y1: Y(d), y2: Y(d), stroke: "#e3e7eb"}),
                svg("text", {x: L - 6, y: Y(d) + 4, "text-anchor": "end"}, String(10 ** d)));
  }
  plot.append(svg("text", {x: (L + W - R) / 2, y: H - 8, "text-anchor": "middle"}, "time (s)"),
              svg("text", {x: 14, y: (T + H - B) / 2, transform: `rotate(-90 14 ${(T + H - B) / 2})`,
                           "text-anchor": "middle"}, "rel_l1 against " + vs));
  const colours = ["#2f6fb3", "#c62828", "#2e7d32", "#b26a00", "#6a1b9a", "#00838f", "#5d4037", "#455a64"];
  const methods = [...new Set(pts.map((r) => r.method))];
  methods.forEach((m, i) => {
    const c = colours[i % colours.length];
    const mine = pts.filter((r) => r.method === m).sort((a, b) => a.time_s - b.time_s);
    if (mine.length > 1)
      plot.append(svg("polyline", {fill: "none", stroke: c, "stroke-opacity": 0.5,
                                   points: mine.map((r) => X(Math.log10(r.time_s)) + "," + Y(Math.log10(errorOf(r)))).join(" ")}));
    for (const r of mine) {
      const dot = svg("circle", {cx: X(Math.log10(r.time_s)), cy: Y(Math.log10(errorOf(r))), r: 4, fill: c});
      dot.append(svg("title", {}, `${m} ${r.setting} (${r.lights} lights): ${r.time_s.toFixed(2)} s, rel_l1 ${errorOf(r).toFixed(4)}`));
      plot.append(dot);
    }
    plot.append(svg("circle", {cx: W - R + 16, cy: T + 10 + 18 * i, r: 4, fill: c}),
                svg("text", {x: W - R + 26, y: T + 14 + 18 * i}, m));
  });
  return plot;
}

async function benchView(view) {
  const {scenes} = await api("/api/v1/bench");
  const only = new URLSearchParams(window.location.search).get("scene");
  const names = Object.keys(scenes).filter((s) => !only || s === only).sort();
  show(view, el("h1", {}, only ? "Bench: " + only : "Bench results"),
    names.length === 0 ? el("p", {class: "muted"},
      only ? "No bench results for " + only + "." :
             "No bench results: start the coordinator with --bench-dir DIR holding `lightfarm bench --out-dir` directories.") : null,
    ...names.map((s) => el("section", {class: "plot"}, el("h2", {}, s), benchPlot(s, scenes[s].rows))));
}

// --- router --------------------------------------------------------------------------------------------

let timer = null;

async function refresh() {
  clearTimeout(timer);
  const view = document.getElementById("view");
  const path = window.location.pathname;
  const job = path.match(/^\/jobs\/(\d+)$/);
  let again = true;
  try {
    if (job) await jobView(view, job[1]);
    else if (path === "/workers") await workersView(view);
    else if (path === "/bench") { await benchView(view); again = false; }
    else await jobsView(view);
    if (!document.getElementById("status-line").classList.contains("error"))
      setStatus("updated " + new Date().toLocaleTimeString());
  } catch (err) {
    setStatus(err.message, true);
  }
  document.body.dataset.loaded = "1";  // for tests: the first render has happened
  if (again) timer = setTimeout(refresh, REFRESH_MS);
}

document.addEventListener("DOMContentLoaded", () => {
  const section = window.location.pathname.startsWith("/workers") ? "nav-workers" :
                  window.location.pathname.startsWith("/bench") ? "nav-bench" : "nav-jobs";
  document.getElementById(section).classList.add("active");
  refresh();
});
