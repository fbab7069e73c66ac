// meshatlas pages: `/` lists recent jobs and uploads a mesh; `/v1/jobs/{id}`
// shows one job, polling its JSON until the state is terminal. The DOM is
// built with createElement/textContent only, so no server value is ever read
// as markup. With a token (asked after a 401, kept in sessionStorage) every
// request carries `Authorization`, and images and downloads go through
// fetch -> blob -> object URL; without one they are plain URLs.
'use strict';

const TOKEN_KEY = 'meshatlas.token';
const TERMINAL = new Set(['succeeded', 'failed', 'cancelled']);
const POLL_MS = 500;
const STAGES = ['atlas', 'crossfield', 'frames', 'quads'];
/** Longest list shown in a summary table before "… N more". */
const MAX_ITEMS = 40;

/** An element with attributes (`text` sets textContent) and children. */
function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === null || v === undefined || v === false) continue;
    if (k === 'text') e.textContent = String(v);
    else e.setAttribute(k, v === true ? '' : String(v));
  }
  for (const c of children) e.append(c instanceof Node ? c : String(c));
  return e;
}

/** True for a path on this server (never `javascript:` or another host). */
function sameOrigin(url) {
  return typeof url === 'string' && url.startsWith('/') && !url.startsWith('//');
}

function token() { return sessionStorage.getItem(TOKEN_KEY); }

/** `Accept: application/json`, plus the bearer token when one is in use. */
function headers() {
  const h = { Accept: 'application/json' };
  if (token()) h.Authorization = 'Bearer ' + token();
  return h;
}

/** Shows the token box after a 401 (a refused token is forgotten). */
function askToken(problem) {
  if (token()) sessionStorage.removeItem(TOKEN_KEY);
  const box = document.getElementById('auth');
  box.hidden = false;
  document.getElementById('auth-message').textContent = (problem && problem.detail) || 'A token is needed.';
}

/** Sets up the token form: the token is stored and the page reloaded. */
function setupTokenForm() {
  document.getElementById('auth-form').addEventListener('submit', (ev) => {
    ev.preventDefault();
    const t = document.getElementById('auth-token').value.trim();
    if (t) { sessionStorage.setItem(TOKEN_KEY, t); location.reload(); }
  });
}

/** Calls the JSON API; `{status, ok, body}` (body null when not JSON). */
async function api(path, opts) {
  const resp = await fetch(path, Object.assign({}, opts, { headers: headers() }));
  let body = null;
  try { body = await resp.json(); } catch (_) { body = null; }
  if (resp.status === 401) askToken(body);
  return { status: resp.status, ok: resp.ok, body };
}

/** A problem+json body (or a network failure) as a titled box. */
function problemBox(problem, fallback) {
  const p = problem || {};
  return el('div', { class: 'problem', role: 'alert' },
    el('strong', { text: p.title || fallback || 'Request failed' }),
    p.detail ? el('div', { class: 'detail', text: p.detail }) : '',
    p.request_id ? el('div', { class: 'muted', text: 'request id ' + p.request_id }) : '');
}

/** `n` bytes as B, KiB, MiB or GiB (three significant digits). */
function humanBytes(n) {
  const units = ['B', 'KiB', 'MiB', 'GiB', 'TiB'];
  let v = n, u = 0;
  while (v >= 1024 && u < units.length - 1) { v /= 1024; u += 1; }
  return u === 0 ? n + ' B' : (v >= 100 ? v.toFixed(0) : v >= 10 ? v.toFixed(1) : v.toFixed(2)) + ' ' + units[u];
}

/** A scalar for a table cell: numbers to 4 significant digits, booleans yes/no. */
function scalar(v) {
  if (v === null || v === undefined) return '—';
  if (typeof v === 'boolean') return v ? 'yes' : 'no';
  if (typeof v === 'number' && !Number.isInteger(v)) return String(Number(v.toPrecision(4)));
  return String(v);
}

function isScalar(v) { return v === null || typeof v !== 'object'; }

/** Any JSON value as DOM: objects as key/value tables, lists of objects as
 * tables with one column per key, lists of scalars as comma lists. */
function valueNode(v) {
  if (isScalar(v)) return el('span', { text: scalar(v) });
  if (Array.isArray(v)) {
    if (v.length === 0) return el('span', { class: 'muted', text: 'none' });
    const shown = v.slice(0, MAX_ITEMS);
    const more = v.length > MAX_ITEMS ? el('div', { class: 'muted', text: '… ' + (v.length - MAX_ITEMS) + ' more' }) : '';
    if (v.every(isScalar)) return el('span', { text: shown.map(scalar).join(', ') + (more ? ', …' : '') });
    if (v.every((x) => x && typeof x === 'object' && !Array.isArray(x))) return el('div', {}, rowsTable(shown), more);
    return el('div', {}, ...shown.map(valueNode), more);
  }
  if (Object.keys(v).length === 0) return el('span', { class: 'muted', text: 'none' });
  const t = el('table', { class: 'kv' });
  for (const [k, x] of Object.entries(v)) t.append(el('tr', {}, el('th', { text: k }), cell(x)));
  return t;
}

/** A table cell for `v` (numbers right-aligned). */
function cell(v) {
  return el('td', { class: typeof v === 'number' ? 'num' : null }, valueNode(v));
}

/** A list of objects as one table, a column per key seen. */
function rowsTable(rows) {
  const keys = [...new Set(rows.flatMap((r) => Object.keys(r)))];
  return el('table', {},
    el('thead', {}, el('tr', {}, ...keys.map((k) => el('th', { text: k })))),
    el('tbody', {}, ...rows.map((r) => el('tr', {}, ...keys.map((k) => cell(r[k]))))));
}

/** The value at `path` ('a.b.c') of `obj`, or undefined. */
function at(obj, path) {
  return path.split('.').reduce((o, k) => (o && typeof o === 'object' ? o[k] : undefined), obj);
}

/** Headline rows of a summary: [label, path]; rows whose value is absent are left out. */
const HEADLINES = [
  ['vertices', 'input.n_vertices'], ['triangles', 'input.n_triangles'], ['tetrahedra', 'input.n_tets'],
  ['components', 'repair.n_components'], ['genus', 'repair.genus'], ['closed', 'repair.closed'],
  ['vertices welded', 'repair.n_vertices_welded_exact'],
  ['patches', 'stages.atlas.n_patches'], ['model faces', 'stages.atlas.n_model_faces'],
  ['feature curves', 'stages.atlas.n_feature_curves'],
  ['singularities', 'stages.crossfield.n_singularities'],
  ['singularities by index', 'stages.crossfield.singularity_counts'],
  ['crossfield energy', 'stages.crossfield.energy'],
  ['frames tetrahedra', 'stages.frames.tets'], ['frames energy', 'stages.frames.energy_after'],
  ['singular edges, valence 3', 'stages.frames.singular.n_valence3'],
  ['singular edges, valence 5', 'stages.frames.singular.n_valence5'],
  ['quads', 'stages.quads.n_quads'], ['irregular vertices', 'stages.quads.n_irregular_vertices'],
  ['inverted quads', 'stages.quads.n_inverted'], ['min scaled Jacobian', 'stages.quads.scaled_jacobian_min'],
  ['total seconds', 'total_seconds'],
];

/** The summary: a headline table, then every section of it generically
 * (`timings` and `artifacts` are shown as stage seconds and downloads). */
function summaryNode(summary) {
  if (!summary || typeof summary !== 'object') return el('p', { class: 'empty', text: 'No summary.' });
  const head = el('table', { class: 'kv', id: 'headline' });
  for (const [label, path] of HEADLINES) {
    const v = at(summary, path);
    if (v !== undefined && v !== null) head.append(el('tr', {}, el('th', { text: label }), cell(v)));
  }
  const sections = Object.entries(summary).filter(([k]) => k !== 'timings' && k !== 'artifacts');
  const section = (name, v) => el('details', { class: 'section' }, el('summary', { text: name }), valueNode(v));
  const parts = sections.map(([k, v]) => (k === 'stages' && v && typeof v === 'object')
    ? Object.entries(v).map(([s, r]) => section(s, r))
    : [section(k, v)]);
  return el('div', {}, head, el('p', { class: 'muted', text: 'Every field of the summary:' }), ...parts.flat());
}

/** Loads `url` into `img`: directly, or through fetch with the token. */
async function loadImage(img, url) {
  if (!token()) { img.src = url; return; }
  try {
    const resp = await fetch(url, { headers: headers() });
    if (!resp.ok) throw new Error(resp.status);
    img.src = URL.createObjectURL(await resp.blob());
  } catch (_) { img.dispatchEvent(new Event('error')); }
}

/** One figure per image artifact; a preview that fails disappears. */
function previewsNode(artifacts) {
  const images = artifacts.filter((a) => String(a.media_type).startsWith('image/') && sameOrigin(a.url));
  if (!images.length) return el('p', { class: 'empty', text: 'No previews for this job.' });
  const box = el('div', { class: 'previews' });
  for (const a of images) {
    const img = el('img', { alt: a.name, 'data-artifact': a.name });
    const fig = el('figure', {}, img, el('figcaption', { text: a.name }));
    img.addEventListener('load', () => {
      img.dataset.naturalWidth = img.naturalWidth;
      img.dataset.naturalHeight = img.naturalHeight;
    });
    img.addEventListener('error', () => { img.dataset.failed = 'true'; fig.hidden = true; });
    box.append(fig);
    loadImage(img, a.url);
  }
  return box;
}

/** Saves `url` with the token: fetch, object URL, a temporary link. */
async function downloadWithToken(url, name) {
  const resp = await fetch(url, { headers: headers() });
  if (!resp.ok) { alert('Download failed: HTTP ' + resp.status); return; }
  const href = URL.createObjectURL(await resp.blob());
  const a = el('a', { href, download: name });
  document.body.append(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(href), 10000);
}

/** The downloads table: every artifact with its media type and size. */
function downloadsNode(artifacts) {
  if (!artifacts.length) return el('p', { class: 'empty', text: 'No artifacts.' });
  const rows = artifacts.filter((a) => sameOrigin(a.url)).map((a) => {
    const link = el('a', { class: 'download', href: a.url, 'data-bytes': a.bytes, text: a.name });
    link.addEventListener('click', (ev) => {
      if (token()) { ev.preventDefault(); downloadWithToken(a.url, a.name); }
    });
    return el('tr', {}, el('td', {}, link), el('td', { text: a.media_type }),
      el('td', { class: 'num size', title: a.bytes + ' bytes', text: humanBytes(a.bytes) }));
  });
  return el('table', { id: 'downloads' },
    el('thead', {}, el('tr', {}, el('th', { text: 'file' }), el('th', { text: 'type' }), el('th', { text: 'size' }))),
    el('tbody', {}, ...rows));
}

/** Seconds per step as a table. */
function secondsNode(stageSeconds) {
  const entries = Object.entries(stageSeconds || {});
  if (!entries.length) return el('p', { class: 'empty', text: 'No step has finished yet.' });
  return el('table', { id: 'stage-seconds' }, el('tbody', {}, ...entries.map(([k, v]) =>
    el('tr', {}, el('th', { text: k }), el('td', { class: 'num', text: v.toFixed(3) + ' s' })))));
}

/** The job page's fixed parts; `update` redraws them from a job resource. */
function jobView(main) {
  const title = el('h1', { text: 'Job' });
  const meta = el('p', { class: 'muted' });
  const state = el('span', { class: 'state', id: 'state', text: '…' });
  const stage = el('span', { id: 'stage' });
  const bar = el('progress', { id: 'progress', max: 1, value: 0, 'data-progress': 0 });
  const percent = el('span', { id: 'percent', text: '0 %' });
  const status = el('p', { class: 'muted', id: 'status-message' });
  const error = el('div', { id: 'error' });
  const seconds = el('div', {});
  const previews = el('div', {});
  const downloads = el('div', {});
  const summary = el('div', {});
  main.replaceChildren(title, meta, el('div', { class: 'progress' }, state, bar, percent, stage), status, error,
    previews, el('div', { class: 'columns' }, downloads, el('div', {}, el('h2', { text: 'Seconds per step' }), seconds)),
    summary);
  return {
    update(job) {
      const done = job.state === 'succeeded';
      const p = done ? 1 : Math.min(1, Math.max(0, Number(job.progress) || 0));
      title.textContent = (job.input && job.input.name) || 'Job';
      document.title = title.textContent + ' — meshatlas';
      meta.textContent = 'job ' + job.id + ' · created ' + job.created_at +
        (job.finished_at ? ' · finished ' + job.finished_at : '');
      state.textContent = job.state;
      state.className = 'state state-' + job.state;
      stage.textContent = job.stage && !TERMINAL.has(job.state) ? 'stage: ' + job.stage : '';
      bar.value = p;
      bar.dataset.progress = Math.round(p * 100);
      percent.textContent = Math.round(p * 100) + ' %';
      status.textContent = job.status_message || '';
      error.replaceChildren(job.error ? problemBox(job.error, 'The job failed') : '');
      seconds.replaceChildren(secondsNode(job.stage_seconds));
    },
    finish(job) {
      const artifacts = Array.isArray(job.artifacts) ? job.artifacts : [];
      const images = artifacts.some((a) => String(a.media_type).startsWith('image/'));
      if (images || job.state === 'succeeded') {
        previews.replaceChildren(el('h2', { text: 'Previews' }), previewsNode(artifacts));
      }
      downloads.replaceChildren(el('h2', { text: 'Downloads' }), downloadsNode(artifacts));
      summary.replaceChildren(el('h2', { text: 'Summary' }), summaryNode(job.summary));
      document.body.dataset.final = job.state;
    },
  };
}

function sleep(ms) { return new Promise((r) => setTimeout(r, ms)); }

/** The job page: polls `GET <this path>` as JSON until the job is final. */
async function showJob(main) {
  const view = jobView(main);
  for (;;) {
    let r;
    try { r = await api(location.pathname); } catch (_) {
      document.getElementById('status-message').textContent = 'The server does not answer; retrying…';
      await sleep(4 * POLL_MS);
      continue;
    }
    if (!r.ok) {
      main.replaceChildren(el('h1', { text: 'Job' }), problemBox(r.body, 'HTTP ' + r.status));
      document.body.dataset.final = 'error';
      return;
    }
    view.update(r.body);
    if (TERMINAL.has(r.body.state)) { view.finish(r.body); return; }
    await sleep(POLL_MS);
  }
}

/** The upload form: file and stages, posted to /v1/jobs, then the job page. */
function uploadForm() {
  const file = el('input', { type: 'file', id: 'file', name: 'file', required: true });
  const boxes = STAGES.map((s) => el('label', { class: 'stage' },
    el('input', { type: 'checkbox', name: 'stage', value: s }), ' ' + s));
  const submit = el('button', { type: 'submit', id: 'submit', text: 'Submit' });
  const message = el('div', { id: 'upload-message', role: 'status' });
  const form = el('form', { id: 'upload', class: 'panel' },
    el('label', { for: 'file', text: 'Mesh file (STL, OBJ, PLY, MSH) ' }), file,
    el('fieldset', {}, el('legend', { text: 'Stages (load and repair always run)' }), ...boxes), submit, message);
  form.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    if (!file.files.length) return;
    const stages = [...form.querySelectorAll('input[name=stage]:checked')].map((b) => b.value);
    const data = new FormData();
    data.append('file', file.files[0], file.files[0].name);
    submit.disabled = true;
    message.replaceChildren(el('p', { class: 'muted', text: 'Uploading…' }));
    let r;
    try { r = await api('/v1/jobs?stages=' + stages.join(','), { method: 'POST', body: data }); } catch (_) {
      r = { status: 0, body: { title: 'The server does not answer' } };
    }
    submit.disabled = false;
    if ((r.status === 201 || r.status === 202) && r.body && sameOrigin(r.body.url)) { location.assign(r.body.url); return; }
    message.replaceChildren(problemBox(r.body, 'HTTP ' + r.status));
  });
  return form;
}

/** Recent jobs as a table linking to their pages. */
function jobsTable(jobs) {
  if (!jobs.length) return el('p', { class: 'empty', text: 'No jobs yet.' });
  const rows = jobs.filter((j) => sameOrigin(j.url)).map((j) => el('tr', {},
    el('td', {}, el('a', { href: j.url, text: (j.input && j.input.name) || j.id })),
    el('td', { text: ((j.params && j.params.stages) || []).join(', ') || '—' }),
    el('td', {}, el('span', { class: 'state state-' + j.state, text: j.state })),
    el('td', { class: 'num', text: Math.round((Number(j.progress) || 0) * 100) + ' %' }),
    el('td', { text: j.created_at })));
  return el('table', { id: 'jobs' },
    el('thead', {}, el('tr', {}, ...['input', 'stages', 'state', 'progress', 'created'].map((h) => el('th', { text: h })))),
    el('tbody', {}, ...rows));
}

/** The start page: upload form and the 20 newest jobs. */
async function showIndex(main) {
  const list = el('div', { id: 'recent' }, el('p', { class: 'muted', text: 'Loading…' }));
  main.replaceChildren(el('h2', { text: 'New job' }), uploadForm(), el('h2', { text: 'Recent jobs' }), list);
  try {
    const r = await api('/v1/jobs?limit=20');
    list.replaceChildren(r.ok ? jobsTable(r.body.jobs || []) : problemBox(r.body, 'HTTP ' + r.status));
  } catch (_) {
    list.replaceChildren(problemBox(null, 'The server does not answer'));
  }
}

document.addEventListener('DOMContentLoaded', () => {
  setupTokenForm();
  const main = document.getElementById('main');
  if (location.pathname.startsWith('/v1/jobs/')) showJob(main); else showIndex(main);
});
