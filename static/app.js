// The wavrad web page: pick or paste a job document, submit it, follow its progress over
// Server-Sent Events and show the images, the per-surface means and the metrics.
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

async function pickScene(name) {
  if (!name) return;
  const doc = await (await fetch(`/scenes/${name}.json`)).json();
  $("doc").value = JSON.stringify(doc, null, 2);
  const s = doc.solver || {};
  $("method").value = s.method || "projection";
  $("basis").value = s.basis || "wavelet";
  $("order").value = s.order ?? 1;
  $("resolution").value = s.resolution ?? 8;
  const keep = s.keep;
  if (!keep || keep === "all") { $("keep-kind").value = "all"; $("keep-value").value = ""; }
  else { const k = Object.keys(keep)[0]; $("keep-kind").value = k; $("keep-value").value = keep[k]; }
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

function documentFromInputs() {
  const doc = JSON.parse($("doc").value);
  if (typeof doc !== "object" || doc === null || Array.isArray(doc)) throw new Error("the document must be a JSON object");
  doc.solver = Object.assign({}, doc.solver);
  doc.solver.method = $("method").value;
  doc.solver.basis = $("basis").value;
  doc.solver.order = Number($("order").value);
  doc.solver.resolution = Number($("resolution").value);
  const kind = $("keep-kind").value;
  if (kind === "all") delete doc.solver.keep;
  else doc.solver.keep = { [kind]: Number($("keep-value").value) };
  return doc;
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
  let doc;
  try { doc = documentFromInputs(); }
  catch (e) { showErrors([{ path: "", message: `not valid JSON: ${e.message}` }]); return; }
  $("submit").disabled = true;
  try {
    const res = await fetch("/api/v1/jobs", { method: "POST",
      headers: { "Content-Type": "application/json" }, body: JSON.stringify(doc) });
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

const fmt = (x) => (x === null || x === undefined) ? "—" : (typeof x === "number" ? Number(x.toPrecision(6)).toString() : String(x));

async function showResult(status) {
  const result = await (await fetch(status.links.result)).json();
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
}

$("scene-select").addEventListener("change", (e) => pickScene(e.target.value));
$("submit").addEventListener("click", submit);
loadScenes();
