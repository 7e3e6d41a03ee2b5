// The wavrad web page: pick or paste a job document, or open a model file, submit it, follow
// its progress over Server-Sent Events and show the images, the per-surface means, the metrics
// and, for 3d scenes, the solved scene in 3D (view3d.js, three.js; image.png without WebGL).
"use strict";

const $ = (id) => document.getElementById(id);
const CONTROLS = { method: "/solver/method", basis: "/solver/basis", order: "/solver/order",
  resolution: "/solver/resolution", keep: "/solver/keep" };
let events = null;

async function loadScenes() {
  const names = await (await fetch("/scenes/index.json")).json();
  for (const n of names) {
    const o = document.createElement("option");
    o.value = n; o.textContent = n; $("scene-select").appendChild(o);
  }
  $("scene-select").value = names[0];
  await pickScene(names[0]);
}

// JSON numbers as written: where the browser can (JSON.rawJSON), a document parsed with
// `asWritten` and serialised again keeps `555.0` as `555.0`, so that a changed control does
// not change the document's other numbers (and its job id).
const rawJSON = typeof JSON.rawJSON === "function" && typeof JSON.isRawJSON === "function";
const asWritten = (text) => JSON.parse(text, (k, v, ctx) =>
  (rawJSON && typeof v === "number" && ctx && typeof ctx.source === "string") ? JSON.rawJSON(ctx.source) : v);
const value = (x) => (rawJSON && JSON.isRawJSON(x)) ? Number(x.rawJSON) : x;
// A result with exact integers: an integer beyond 2^53 becomes a BigInt, not a rounded Number.
const exact = (text) => JSON.parse(text, (k, v, ctx) =>
  (typeof v === "number" && !Number.isSafeInteger(v) && ctx && /^-?[0-9]+$/.test(ctx.source || "")) ? BigInt(ctx.source) : v);

// A document as text: an object one key a line, indented; an array of numbers, or of arrays
// of numbers (corners, a mesh's positions and triangles), on one line. An imported model of
// 10⁴ triangles so stays a few hundred kB, within what the server takes (`max_body_bytes`),
// not megabytes of indentation.
function written(v, pad = "") {
  const leaf = (x) => x === null || typeof x !== "object" || (rawJSON && JSON.isRawJSON(x));
  if (leaf(v) || (Array.isArray(v) && v.every((x) => leaf(x) || (Array.isArray(x) && x.every(leaf)))))
    return JSON.stringify(v);
  const inner = pad + "  ";
  const lines = Array.isArray(v)
    ? v.map((x) => inner + written(x, inner))
    : Object.keys(v).map((k) => `${inner}${JSON.stringify(k)}: ${written(v[k], inner)}`);
  const [open, close] = Array.isArray(v) ? ["[", "]"] : ["{", "}"];
  return lines.length ? `${open}\n${lines.join(",\n")}\n${pad}${close}` : open + close;
}

const DEFAULTS = { method: "projection", basis: "wavelet", order: 1, resolution: 8 };

async function pickScene(name) {
  if (!name) return;
  // the document exactly as the file has it
  useDocument(await (await fetch(`/scenes/${name}.json`)).text());
}

// A document into the text area, and its solver into the controls.
function useDocument(text) {
  $("doc").value = text;
  showSolver(text);
}

// The document's solver into the controls (when the text is a JSON object; while it is being
// typed and is not, the controls keep what they show).
function showSolver(text) {
  let doc;
  try { doc = JSON.parse(text); } catch (_) { return; }
  if (typeof doc !== "object" || doc === null || Array.isArray(doc)) return;
  const s = doc.solver || {};
  for (const k of Object.keys(DEFAULTS)) $(k).value = s[k] ?? DEFAULTS[k];
  const keep = s.keep;
  if (!keep || keep === "all") { $("keep-kind").value = "all"; $("keep-value").value = ""; }
  else { const k = Object.keys(keep)[0]; $("keep-kind").value = k; $("keep-value").value = keep[k]; }
}

// The content types of model files sent alone (POST /api/v1/import).
const MODEL_TYPES = { obj: "model/obj", gltf: "model/gltf+json", glb: "model/gltf-binary" };
const extension = (f) => f.name.toLowerCase().split(".").pop();

// "Open a model": the chosen file alone with its content type, or with the files it refers to
// (an OBJ's MTL, a glTF's .bin) as multipart/form-data; the answer, a job document, goes into
// the text area.
async function openModel(files) {
  clearErrors();
  if (!files.length) return;
  const model = files.find((f) => extension(f) in MODEL_TYPES);
  if (!model) { showErrors([{ path: "", message: "choose an .obj, .gltf or .glb file" }]); return; }
  let init;
  if (files.length === 1) {
    init = { method: "POST", headers: { "Content-Type": MODEL_TYPES[extension(model)] }, body: model };
  } else {
    const form = new FormData();
    for (const f of files) form.append(f === model ? "model" : "file", f, f.name);
    init = { method: "POST", body: form };
  }
  const res = await fetch("/api/v1/import", init);
  const body = await res.json().catch(() => ({ title: `HTTP ${res.status}`, detail: "" }));
  if (!res.ok) {
    showErrors(body.errors && body.errors.length ? body.errors : [{ path: "", message: `${body.title}: ${body.detail}` }]);
    return;
  }
  $("scene-select").value = "";
  useDocument(written(body));
}

function clearErrors() {
  $("errors").innerHTML = "";
  $("failure").textContent = "";
  for (const el of document.querySelectorAll(".field-error")) if (el.id !== "failure") el.textContent = "";
  for (const el of document.querySelectorAll(".invalid")) el.classList.remove("invalid");
}

function showErrors(list) {
  for (const e of list) {
    const li = document.createElement("li");
    li.dataset.path = e.path;
    const code = document.createElement("code");
    code.textContent = e.path || "/";
    li.append(code, " ", e.message);
    $("errors").appendChild(li);
    const control = Object.keys(CONTROLS).find((c) => e.path.startsWith(CONTROLS[c]));
    const target = control || "doc";
    $(target + "-error").textContent += `${e.path || "/"}: ${e.message} `;
    $(target === "keep" ? "keep-kind" : target).classList.add("invalid");
  }
}

// The text to send: the text area as written when the controls say what the document says
// (a missing field and its default are the same); otherwise the document with the controls'
// values, written back to the text area first so that what is sent is what is shown.
function documentText() {
  const text = $("doc").value;
  const doc = asWritten(text);
  if (typeof doc !== "object" || doc === null || Array.isArray(doc)) throw new Error("the document must be a JSON object");
  const given = (doc.solver && typeof doc.solver === "object") ? doc.solver : {};
  const solver = Object.assign({}, given);
  const want = { method: $("method").value, basis: $("basis").value,
    order: Number($("order").value), resolution: Number($("resolution").value) };
  let changed = false;
  for (const k of Object.keys(want)) {
    const have = k in given ? value(given[k]) : DEFAULTS[k];
    if (have !== want[k]) { solver[k] = want[k]; changed = true; }
  }
  const keep = given.keep;
  const haveKind = (!keep || keep === "all") ? "all" : Object.keys(keep)[0];
  const haveValue = haveKind === "all" ? null : value(keep[haveKind]);
  const kind = $("keep-kind").value;
  const wantValue = kind === "all" ? null : Number($("keep-value").value);
  if (kind !== haveKind || wantValue !== haveValue) {
    if (kind === "all") delete solver.keep; else solver.keep = { [kind]: wantValue };
    changed = true;
  }
  if (!changed) return text;
  doc.solver = solver;
  const out = written(doc);
  $("doc").value = out;
  return out;
}

function showStatus(s) {
  $("job-id").textContent = s.id;
  $("state").textContent = s.state;
  $("phase").textContent = s.progress.phase;
  $("fraction").textContent = `${Math.round(s.progress.fraction * 100)}%`;
  $("progress").value = s.state === "succeeded" ? 1 : s.progress.fraction;
  if (s.state === "failed" && s.error) $("failure").textContent = `${s.error.title}: ${s.error.detail}`;
}

async function submit() {
  clearErrors();
  let text;
  try { text = documentText(); }
  catch (e) { showErrors([{ path: "", message: `not valid JSON: ${e.message}` }]); return; }
  $("submit").disabled = true;
  try {
    const res = await fetch("/api/v1/jobs", { method: "POST",
      headers: { "Content-Type": "application/json" }, body: text });
    const body = await res.json();
    if (!res.ok) {
      showErrors(body.errors && body.errors.length ? body.errors : [{ path: "", message: `${body.title}: ${body.detail}` }]);
      return;
    }
    follow(body);
  } finally { $("submit").disabled = false; }
}

function follow(status) {
  if (events) events.close();
  for (const id of ["image", "sparsity", "coefficients"]) $(id).removeAttribute("src");
  $("surfaces-body").innerHTML = ""; $("metrics").innerHTML = ""; $("result-link").hidden = true;
  $("warnings").innerHTML = ""; $("warnings-panel").hidden = true;
  hideModel();
  showStatus(status);
  if (status.state === "succeeded") { showResult(status); return; }
  events = new EventSource(status.links.events);
  events.addEventListener("status", (ev) => {
    const s = JSON.parse(ev.data);
    showStatus(s);
    if (["succeeded", "failed", "cancelled"].includes(s.state)) {
      events.close(); events = null;
      if (s.state === "succeeded") showResult(s);
    }
  });
}

// Integers exactly (counts of entries, links, rays), other numbers to six digits.
const fmt = (x) => {
  if (x === null || x === undefined) return "—";
  if (typeof x === "bigint") return x.toString();
  if (typeof x === "number") return Number.isInteger(x) ? x.toString() : Number(x.toPrecision(6)).toString();
  return String(x);
};

function showWarnings(list) {
  const ul = $("warnings");
  ul.innerHTML = "";
  for (const w of list || []) {
    const li = document.createElement("li");
    for (const p of w.paths) {
      const code = document.createElement("code"); code.textContent = p; li.append(code, " ");
    }
    li.append(w.message);
    ul.appendChild(li);
  }
  $("warnings-panel").hidden = ul.children.length === 0;
}

async function showResult(status) {
  const result = exact(await (await fetch(status.links.result)).text());
  showWarnings(result.warnings);
  const body = $("surfaces-body");
  body.innerHTML = "";
  result.surfaces.forEach((s, i) => {
    const tr = document.createElement("tr");
    tr.dataset.name = s.name;
    const name = document.createElement("td"); name.textContent = s.name; tr.appendChild(name);
    s.mean.forEach((v, c) => {
      const td = document.createElement("td"); td.id = `mean-${i}-${c}`; td.className = "mean";
      td.textContent = fmt(v); tr.appendChild(td);
    });
    const pic = document.createElement("td"); const img = document.createElement("img");
    img.alt = `B over ${s.name}`; img.src = status.links.surfaces[s.name];
    const full = document.createElement("a"); full.href = img.src; full.target = "_blank";
    full.appendChild(img); pic.appendChild(full); tr.appendChild(pic);
    body.appendChild(tr);
  });
  const m = result.metrics, c = result.coefficients;
  const rows = [
    ["kernel relative error (5)", m.kernel_relative_error],
    ["radiosity relative error (6)", m.radiosity_relative_error],
    ["reference", m.reference],
    ["iterations", m.iterations], ["converged", m.converged], ["final residual", m.final_residual],
    ["energy balance", m.energy.balance.map(fmt).join(", ")],
    ["basis size", c.basis_size], ["matrix entries", c.matrix_entries], ["kept entries", c.kept_entries],
    ["sparsity ratio", c.sparsity_ratio], ["total time (ms)", result.timings_ms.total],
  ];
  if (m.kernel_evaluations !== undefined) rows.push(["kernel evaluations", m.kernel_evaluations]);
  if (result.hierarchical) {
    const h = result.hierarchical;
    rows.push(["elements", h.elements], ["links", h.links], ["rays", h.rays]);
  }
  const dl = $("metrics"); dl.innerHTML = "";
  for (const [k, v] of rows) {
    const dt = document.createElement("dt"); dt.textContent = k;
    const dd = document.createElement("dd"); dd.textContent = fmt(v);
    dd.id = "metric-" + k.split(" (")[0].replace(/\s+/g, "-");
    dl.append(dt, dd);
  }
  $("result-link").href = status.links.result; $("result-link").hidden = false;
  $("sparsity").src = status.links.sparsity;
  $("coefficients").src = status.links.coefficients;
  $("image").src = status.links.image;
  showModel(status);
}

let viewer = null;

function hideModel() {
  if (viewer) viewer.clear();
  $("view3d").innerHTML = "";
  $("view3d-panel").hidden = true;
  $("view3d-note").textContent = "Drag to turn, scroll to zoom, right-drag to move.";
  delete $("view3d").dataset.state;
}

// The solved 3d scene in 3D; image.png where the browser has no WebGL (or the view fails).
async function showModel(status) {
  hideModel();
  if (!status.links.model) return;
  $("view3d-panel").hidden = false;
  $("model-link").href = status.links.model;
  const box = $("view3d");
  const fallback = (why) => {
    const img = document.createElement("img");
    img.id = "view3d-fallback"; img.alt = `the scene (${why})`; img.src = status.links.image;
    box.innerHTML = ""; box.appendChild(img);
    box.dataset.state = "image";
    $("view3d-note").textContent = `No 3D view here (${why}): the image instead.`;
  };
  try {
    viewer = await import("/static/view3d.js");
    if (!viewer.hasWebGL()) { fallback("no WebGL"); return; }
    await viewer.show(box, status.links.model);
    box.dataset.state = "3d";
  } catch (e) {
    console.error(e);
    fallback(String(e.message || e));
  }
}

$("scene-select").addEventListener("change", (e) => pickScene(e.target.value));
$("submit").addEventListener("click", submit);
// an edit of the document's solver by hand shows in the controls, so that Solve sends it as
// typed (the controls would otherwise write their older values over it)
$("doc").addEventListener("input", (e) => showSolver(e.target.value));
$("model-file").addEventListener("change", (e) => openModel([...e.target.files]));
loadScenes();
