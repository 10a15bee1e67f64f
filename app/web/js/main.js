// The calf-nurbs workbench: a single-page app on the public /api/v1 (every screen is
// something any client could do).  Hash routes; screens render into <main>.
import { api, apiKey, ApiError, download, uploadScan } from './api.js';
import { lineChart } from './charts.js';
import { grid, gridIndex, makeSurface, ring } from './nurbs.js';
import { colour, createViewer, legendRamp } from './viewer.js';

const main = document.getElementById('main');
const LANDMARKS = ['B', 'B1', 'C', 'D'];
// the order form's thigh points (RAL-GZ 387: middle of the knee, middle and top of the thigh)
const THIGH_POINTS = ['cE', 'cF', 'cG'];
const MESH_FORMATS = ['stl', 'glb', 'gltf'];
const CAD_FORMATS = { step: 'step', iges: 'igs', '3dm': '3dm', geomdl: 'json' };

// ---------------------------------------------------------------- helpers
function h(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === false || v == null) continue;
    if (k.startsWith('on')) node.addEventListener(k.slice(2), v);
    else if (k === 'text') node.textContent = v;
    else node.setAttribute(k, v === true ? '' : v);
  }
  for (const child of children.flat(Infinity)) if (child != null) node.append(child.nodeType ? child : document.createTextNode(child));
  return node;
}
const mm = (x, d = 1) => (Number.isFinite(x) ? x.toFixed(d) : '–');
const status = (text) => { document.getElementById('status').textContent = text; };

function show(...nodes) {
  main.replaceChildren(...nodes.filter((node) => node != null));
  main.focus({ preventScroll: true });
}

// Each navigation is one generation; a screen still waiting on the API when the user has
// moved on must not paint over the screen that replaced it (a slow records list used to
// overwrite the upload form opened meanwhile).  An async screen takes its `present` at its
// start, while the generation is still its own.
let generation = 0;
function presenter() {
  const mine = generation;
  return (...nodes) => { if (mine === generation) show(...nodes); return mine === generation; };
}

function problemBox(error) {
  const p = error instanceof ApiError ? error.problem : { title: 'Error', detail: String(error) };
  return h('div', { class: 'error', role: 'alert' }, h('strong', { text: p.title || 'Error' }), h('div', { text: p.detail || '' }),
    p.code ? h('div', { class: 'muted', text: `reason: ${p.code}` }) : null);
}

async function guarded(render) {
  const present = presenter();
  try {
    await render();
  } catch (error) {
    if (error instanceof ApiError && (error.status === 401 || error.status === 403)) {
      apiKey.clear();
      location.hash = '#/sign-in';
      return;
    }
    present(h('h1', { text: 'Something went wrong' }), problemBox(error));
  }
}

// ---------------------------------------------------------------- sign-in
function signIn(message) {
  const input = h('input', { id: 'api-key', type: 'password', autocomplete: 'off', required: true, placeholder: 'cnk_…' });
  const out = h('div');
  const form = h('form', { class: 'card', onsubmit: async (event) => {
    event.preventDefault();
    apiKey.set(input.value.trim());
    try {
      await api('/records?limit=1');
      location.hash = '#/records';
    } catch (error) {
      apiKey.clear();
      out.replaceChildren(h('div', { class: 'error', role: 'alert', id: 'sign-in-error' },
        h('strong', { text: 'Sign-in failed' }),
        h('div', { text: error instanceof ApiError && (error.status === 401 || error.status === 403)
          ? `The key was not accepted: ${error.message}` : error.message })));
    }
  } },
  h('label', { for: 'api-key', text: 'API key of your clinic' }), input,
  h('p', { class: 'muted', text: 'The key stays in this browser tab only and is forgotten when the tab closes.' }),
  h('button', { class: 'primary', type: 'submit', text: 'Sign in' }), out);
  show(h('h1', { text: 'Sign in' }), message ? h('p', { class: 'muted', text: message }) : null, form);
  input.focus();
}

// ---------------------------------------------------------------- upload
function uploadScreen() {
  let file = null;
  const fileInput = h('input', { id: 'scan-file', type: 'file', 'aria-label': 'Scan file', accept: '.stl,.ply,.obj,.off,.glb,.gltf,.xyz,.csv,.txt,.pts,.asc' });
  const chosen = h('p', { class: 'muted', text: 'No file chosen.' });
  const pick = (f) => { file = f; chosen.textContent = f ? `${f.name} (${(f.size / 1e6).toFixed(1)} MB)` : 'No file chosen.'; };
  fileInput.addEventListener('change', () => pick(fileInput.files[0]));
  const drop = h('div', { class: 'drop', id: 'drop-zone', tabindex: 0, role: 'button', 'aria-label': 'Drop a scan here or press Enter to choose a file',
    onclick: () => fileInput.click(), onkeydown: (e) => { if (e.key === 'Enter' || e.key === ' ') { e.preventDefault(); fileInput.click(); } },
    ondragover: (e) => { e.preventDefault(); drop.classList.add('over'); }, ondragleave: () => drop.classList.remove('over'),
    ondrop: (e) => { e.preventDefault(); drop.classList.remove('over'); pick(e.dataTransfer.files[0]); } },
  h('strong', { text: 'Drop a leg scan here' }), h('div', { class: 'muted', text: 'STL, PLY, OBJ, OFF, GLB/glTF or a point cloud (XYZ, CSV) — or press to choose' }));
  const select = (id, label, options) => [h('label', { for: id, text: label }),
    h('select', { id }, options.map(([value, text]) => h('option', { value, text })))];
  const gridInput = h('input', { id: 'grid', type: 'text', value: '7x15', pattern: '[0-9]{1,2}[xX][0-9]{1,2}' });
  const progress = h('progress', { id: 'upload-progress', max: 1, value: 0, hidden: true, 'aria-label': 'Upload progress' });
  const phase = h('p', { id: 'upload-phase', 'aria-live': 'polite' });
  const out = h('div');
  const form = h('form', { class: 'card', onsubmit: async (event) => {
    event.preventDefault();
    out.replaceChildren();
    if (!file) { out.append(h('div', { class: 'error', role: 'alert', text: 'Choose a scan file first.' })); return; }
    const fields = { side: document.getElementById('side').value, units: document.getElementById('units').value,
      mode: document.getElementById('mode').value, points: document.getElementById('points').value,
      case_ref: document.getElementById('case-ref').value.trim() };
    if (fields.mode === 'lsq') fields.grid = gridInput.value.trim();
    progress.hidden = false; progress.value = 0; phase.textContent = 'Uploading…';
    try {
      const job = await uploadScan(file, fields, (fraction) => { progress.value = fraction * 0.5; phase.textContent = `Uploading… ${Math.round(fraction * 100)}%`; });
      phase.textContent = 'Checked and queued: fitting…';
      let current = job;
      for (let i = 0; i < 600 && !['succeeded', 'failed'].includes(current.status); i++) {
        await new Promise((r) => setTimeout(r, 500));
        current = await api(`/jobs/${job.id}`);
        progress.value = current.status === 'running' ? 0.75 : 0.6;
        phase.textContent = `Fitting: ${current.status}`;
      }
      if (current.status !== 'succeeded') {
        progress.hidden = true;
        phase.textContent = '';
        out.replaceChildren(problemBox(new ApiError({ title: 'The scan could not be fitted', detail: current.error?.detail, code: current.error?.reason }, 422)));
        return;
      }
      progress.value = 1;
      phase.textContent = 'Done.';
      location.hash = `#/records/${current.record_id}`;
    } catch (error) {
      progress.hidden = true;
      phase.textContent = '';
      out.replaceChildren(problemBox(error));
    }
  } },
  drop, fileInput, chosen,
  h('div', { class: 'grid-half' },
    h('div', {}, h('label', { for: 'case-ref', text: 'Case reference (your pseudonymous case id, never a name)' }),
      h('input', { id: 'case-ref', type: 'text', maxlength: 64, pattern: '[A-Za-z0-9][A-Za-z0-9._\\-]{0,63}', autocomplete: 'off',
        placeholder: 'e.g. CASE-0042' }),
      ...select('side', 'Side (for a body or two legs)', [['', 'detect'], ['left', 'left'], ['right', 'right']]),
      ...select('units', 'Units of the file', [['', 'detect from size'], ['mm', 'mm'], ['cm', 'cm'], ['m', 'm'], ['in', 'inches']])),
    h('div', {}, ...select('mode', 'Surface', [['paper', 'paper (7 layers, interpolated)'], ['lsq', 'least squares (all points)']]),
      h('label', { for: 'points', text: 'Feature points per layer (paper)' }), h('input', { id: 'points', type: 'number', min: 4, max: 36, value: 15 }),
      h('label', { for: 'grid', text: 'Control net along x around (least squares)' }), gridInput)),
  h('button', { class: 'primary', type: 'submit', text: 'Upload and fit' }), progress, phase, out);
  show(h('h1', { text: 'Upload a scan' }), form);
}

// ---------------------------------------------------------------- records
async function recordsScreen(params) {
  const present = presenter();
  const query = new URLSearchParams({ limit: '20' });
  for (const k of ['side', 'since', 'until', 'cursor']) if (params.get(k)) query.set(k, params.get(k));
  const page = await api(`/records?${query}`);
  const filter = h('form', { class: 'toolbar card', onsubmit: (e) => {
    e.preventDefault();
    const next = new URLSearchParams();
    for (const k of ['side', 'since', 'until']) { const v = document.getElementById(`filter-${k}`).value; if (v) next.set(k, v); }
    location.hash = `#/records?${next}`;
  } },
  h('label', { for: 'filter-side' }, 'Side ', h('select', { id: 'filter-side' }, ['', 'left', 'right', 'unknown'].map((v) =>
    h('option', { value: v, text: v || 'any', selected: params.get('side') === v })))),
  h('label', { for: 'filter-since' }, 'From ', h('input', { id: 'filter-since', type: 'date', value: params.get('since') || '' })),
  h('label', { for: 'filter-until' }, 'To ', h('input', { id: 'filter-until', type: 'date', value: params.get('until') || '' })),
  h('button', { class: 'secondary', type: 'submit', text: 'Filter' }));
  const rows = page.items.map((r) => {
    const lm = r.landmarks || {};
    const tape = (n) => lm[n]?.tape_girth_mm ?? lm[n]?.circumference_mm;
    return h('tr', {},
      h('td', {}, h('a', { href: `#/records/${r.id}`, text: new Date(r.created_at).toLocaleString() })),
      h('td', { text: r.side || 'unknown' }), h('td', { class: 'num', text: mm(tape('B')) }), h('td', { class: 'num', text: mm(tape('C')) }),
      h('td', { class: 'num', text: r.error_index != null ? `${(100 * r.error_index).toFixed(2)}%` : '–' }),
      h('td', { text: r.source }),
      h('td', {}, h('button', { class: 'danger', type: 'button', 'aria-label': `Delete the record of ${new Date(r.created_at).toLocaleString()}`,
        text: 'Delete', onclick: async () => {
          if (!confirm('Delete this record? Its scan stays stored; the record and its designs cannot be recovered.')) return;
          await guarded(async () => { await api(`/records/${r.id}`, { method: 'DELETE' }); status('Record deleted.'); recordsScreen(params); });
        } })));
  });
  const table = h('table', { id: 'records-table' }, h('caption', { class: 'muted', text: `${page.items.length} records on this page` }),
    h('thead', {}, h('tr', {}, ['Date', 'Side', 'B girth mm', 'C girth mm', 'E', 'Source', ''].map((t, i) => h('th', { class: i >= 2 && i <= 4 ? 'num' : null, text: t })))),
    h('tbody', {}, rows));
  const back = params.get('cursor') ? h('a', { class: 'button', href: '#/records', text: 'First page' }) : null;
  const next = page.next_cursor ? h('a', { class: 'button', href: `#/records?${new URLSearchParams({ ...Object.fromEntries(params), cursor: page.next_cursor })}`, text: 'Next page' }) : null;
  present(h('h1', { text: 'Records' }), filter, h('div', { class: 'card' }, page.items.length ? table : h('p', { class: 'muted', text: 'No records yet: upload a scan.' }),
    h('div', { class: 'pager' }, back, next)));
}

// ---------------------------------------------------------------- record
// ready to wear or made to measure: the record's tape girths against a size chart
function sizeDecisionView(d) {
  if (d.decision === 'ready_to_wear') {
    const others = d.fitting.filter((name) => name !== d.best);
    return [h('p', {}, h('span', { class: 'badge pass', text: 'ready to wear' }), ` Size ${d.best} fits at every point`
      + (others.length ? ` (also: ${others.join(', ')})` : '') + '.')];
  }
  if (d.decision === 'not_measured') {
    return [h('p', {}, h('span', { class: 'badge review', text: 'not measured' }), ` The record does not measure ${d.missing.join(', ')}.`)];
  }
  return [h('p', {}, h('span', { class: 'badge fail', text: 'made to measure' }), ` No size fits; nearest is ${d.nearest}:`),
    h('ul', {}, d.outside.map((c) => h('li', { text: `${c.point} ${c.measured_mm.toFixed(0)} mm is ${Math.abs(c.excess_mm).toFixed(0)} mm `
      + `${c.excess_mm > 0 ? 'above' : 'below'} its range ${c.low_mm}-${c.high_mm} mm` })))];
}

function sizeCard(id, charts) {
  const chartSelect = h('select', { id: 'size-chart' }, charts.map((c) => h('option', { value: c.id, text: c.product })));
  const out = h('div', { id: 'size-decision', 'aria-live': 'polite' });
  return h('div', { class: 'card' }, h('h2', { text: 'Ready-to-wear size' }),
    h('label', { for: 'size-chart', text: 'Size chart' }), chartSelect,
    h('button', { class: 'secondary', type: 'button', text: 'Check the sizes', onclick: () => guarded(async () => {
      out.replaceChildren(...sizeDecisionView(await api(`/records/${id}/size-decision?chart=${encodeURIComponent(chartSelect.value)}`)));
    }) }), out);
}

async function recordScreen(id) {
  const present = presenter();
  const record = await api(`/records/${id}`);
  // "another record of this leg": the same case and the same side only (a record without a
  // case reference has no other record of its leg that the service could vouch for)
  const sameCase = record.case_ref
    ? api(`/records?limit=50&case_ref=${encodeURIComponent(record.case_ref)}&side=${record.side || 'unknown'}`)
    : Promise.resolve({ items: [] });
  const [measure, designs, others, charts] = await Promise.all([api(`/records/${id}/measurements`), api(`/records/${id}/designs`),
    sameCase, api('/size-charts')]);
  const viewerBox = h('div', { class: 'viewer', id: 'record-viewer', 'data-label': 'The NURBS calf surface over the scan points' });
  const legend = h('div', { class: 'legend' });
  const toggles = h('div', { class: 'toolbar' });
  const sheet = measurementSheet(record, measure);
  const profileBox = h('div', { class: 'card' }, h('p', { class: 'muted', text: 'Loading the circumference profile…' }));
  const downloads = h('div', { class: 'card' }, h('h2', { text: 'Downloads' }),
    MESH_FORMATS.map((f) => h('button', { class: 'secondary', type: 'button', text: f.toUpperCase(),
      onclick: () => guarded(() => download(`/records/${id}/surface?format=${f}`, `calf-${id.slice(0, 8)}.${f}`)) })),
    Object.entries(CAD_FORMATS).map(([f, ext]) => h('button', { class: 'secondary', type: 'button', text: `${f.toUpperCase()} (exact)`,
      onclick: () => guarded(() => download(`/records/${id}/surface?format=${f}`, `calf-${id.slice(0, 8)}.${ext}`)) })),
    // the leg model from B to G when the scan reached the top of the thigh, else why not
    record.leg_model && record.leg_model.surface
      ? h('div', { id: 'leg-model-downloads' }, h('h3', { text: 'The leg, B to G (least squares)' }),
        ['stl', 'glb', ...Object.keys(CAD_FORMATS)].map((f) => h('button', { class: 'secondary', type: 'button', text: `Leg ${f.toUpperCase()}`,
          onclick: () => guarded(() => download(`/records/${id}/surface?format=${f}&part=leg`, `leg-${id.slice(0, 8)}.${CAD_FORMATS[f] || f}`)) })))
      : h('p', { class: 'muted', id: 'leg-model-downloads', text: `No leg model above the calf${record.leg_model ? `: ${record.leg_model.reason}` : ''}.` }));
  const designList = h('div', { class: 'card' }, h('h2', { text: 'Stocking designs' }),
    designs.length ? h('ul', {}, designs.map((d) => h('li', {}, h('a', { href: `#/designs/${d.id}`,
      text: `${d.inputs.standard} ${d.inputs.compression_class ?? 'explicit targets'} — ${new Date(d.created_at).toLocaleString()}` }), ' ',
      h('span', { class: `badge ${d.passed ? 'pass' : 'fail'}`, text: d.passed ? 'pass' : 'fail' })))) : h('p', { class: 'muted', text: 'None yet.' }),
    h('a', { class: 'button', href: `#/records/${id}/design`, text: 'New design' }),
    designs.length >= 2 ? h('a', { class: 'button', href: `#/designs/${designs[0].id}/vs/${designs[1].id}`, text: 'Compare the last two designs' }) : null);
  const sameLeg = others.items.filter((r) => r.id !== id);
  const compareSelect = h('select', { id: 'compare-with' }, sameLeg.map((r) => h('option', { value: r.id, text: `${new Date(r.created_at).toLocaleString()} (${r.side || 'unknown'})` })));
  const compareCard = h('div', { class: 'card' }, h('h2', { text: 'Compare over time' }),
    sameLeg.length ? [h('label', { for: 'compare-with', text: 'Another record of this leg' }), compareSelect,
      h('button', { class: 'secondary', type: 'button', text: 'Compare', onclick: () => { location.hash = `#/compare/${id}/${compareSelect.value}`; } })]
      : h('p', { class: 'muted', text: record.case_ref ? `No other record of case ${record.case_ref}, ${record.side || 'unknown'} side, yet.`
        : 'This record has no case reference: upload with a case reference to compare one leg over time.' }));
  if (!present(h('h1', { text: `Record ${record.side ? `— ${record.side} leg` : ''}${record.case_ref ? ` · case ${record.case_ref}` : ''}` }),
    record.warnings?.length ? h('div', { class: 'card warn' }, h('ul', {}, record.warnings.map((w) => h('li', { text: w })))) : null,
    h('div', { class: 'grid2' }, h('div', {}, h('div', { class: 'card' }, viewerBox, toggles, legend), profileBox),
      h('div', {}, sheet, orderPoints(measure.chart || []), downloads, sizeCard(id, charts), designList, compareCard)))) return;
  await Promise.all([draw3d(record, viewerBox, toggles, legend, measure.chart), drawProfile(record, profileBox)]);
}

function measurementSheet(record, measure) {
  const lm = measure.landmarks;
  const table = h('table', { id: 'measurement-sheet' }, h('caption', { class: 'muted', text: 'Measured on the surface; the scan values in brackets' }),
    h('thead', {}, h('tr', {}, ['', 'height above B mm', 'tape girth mm', 'section perimeter mm', 'height placed'].map((t, i) => h('th', { class: i && i < 4 ? 'num' : null, text: t })))),
    h('tbody', {}, LANDMARKS.filter((n) => lm[n]).map((n) => h('tr', { 'data-landmark': n }, h('th', { text: n }),
      h('td', { class: 'num', text: mm(lm[n].height_mm) }),
      h('td', { class: 'num', text: `${mm(lm[n].tape_circumference_mm)} (${mm(lm[n].scan_tape_girth_mm)})` }),
      h('td', { class: 'num', text: `${mm(lm[n].circumference_mm)} (${mm(lm[n].scan_circumference_mm)})` }),
      h('td', { class: `confidence ${lm[n].confidence ?? ''}`, 'data-confidence': lm[n].confidence ?? '',
        text: lm[n].confidence ? `${lm[n].confidence} (±${mm(lm[n].height_tolerance_mm)} mm)` : 'not recorded' })))));
  const floor = measure.above_floor_mm ? Object.entries(measure.above_floor_mm).map(([k, v]) => [`${k} above the floor`, v]) : [];
  const lengths = h('dl', { class: 'sheet', id: 'lengths' }, [...Object.entries(measure.lengths_mm), ...floor]
    .flatMap(([k, v]) => [h('dt', { text: k }), h('dd', { text: `${mm(v)} mm` })]));
  const at = h('input', { id: 'height-input', type: 'number', step: '0.5', min: measure.height_range_mm[0], max: measure.height_range_mm[1] });
  const answer = h('p', { id: 'height-answer', 'aria-live': 'polite' });
  const ask = h('form', { onsubmit: async (e) => {
    e.preventDefault();
    try {
      const r = await api(`/records/${record.id}/measurements?heights=${encodeURIComponent(at.value)}`);
      const g = r.heights[0];
      answer.textContent = `At ${mm(g.height_mm)} mm: tape girth ${mm(g.tape_circumference_mm)} mm, perimeter ${mm(g.circumference_mm)} mm.`;
    } catch (error) { answer.replaceChildren(problemBox(error)); }
  } }, h('label', { for: 'height-input', text: `Girth at a height above B (${mm(measure.height_range_mm[0])} to ${mm(measure.height_range_mm[1])} mm)` }),
  at, h('button', { class: 'secondary', type: 'submit', text: 'Measure' }), answer);
  return h('div', { class: 'card' }, h('h2', { text: 'Measurement sheet' }), table, h('h2', { text: measure.above_floor_mm ? 'Lengths along the leg and from the floor' : 'Lengths along the leg' }), lengths,
    record.fit ? h('p', { class: 'muted', text: `Fit: ${record.fit.mode ?? 'paper'}, E ${(100 * (record.fit.error_index_exact ?? 0)).toFixed(2)}%, max error ${mm(record.fit.max_error_mm, 2)} mm` }) : null,
    ask);
}

// the order form's measuring points (RAL-GZ 387) of a record: value, or why the scan has none
function orderPoints(chart) {
  return h('div', { class: 'card' }, h('h2', { text: 'Order form points' }),
    h('div', { class: 'scroll' }, h('table', { id: 'order-points' },
      h('thead', {}, h('tr', {}, ['point', 'what', 'for', 'value'].map((t) => h('th', { text: t })))),
      h('tbody', {}, chart.map((p) => h('tr', { 'data-point': p.point, 'data-measured': p.value_mm != null ? 'yes' : 'no' },
        h('th', { text: p.point }), h('td', { text: p.description }), h('td', { text: p.needed_for.join(', ') }),
        h('td', { class: p.value_mm != null ? 'num' : 'muted', text: pointValue(p) })))))));
}

// a measured point's value, with how far it may be off where the scan leaves its place
// uncertain: a girth a tape decides; a length whose point's height is uncertain (a flat
// calf crown) reads the same girth anywhere along it, and a tape has the same choice; the
// foot length where the scan is too sparse at the heel or the toes to show the foot's end
function pointValue(p) {
  if (p.value_mm == null) return `not in the scan: ${p.reason}`;
  if (p.uncertainty_mm == null) return `${mm(p.value_mm)} mm`;
  const why = p.point === 'foot_length' ? 'the foot\'s ends are uncertain: take by tape'
    : p.kind === 'length' ? 'the point\'s height is uncertain' : 'uncertain: take by tape';
  return `${mm(p.value_mm)} mm ± ${mm(p.uncertainty_mm)} (${why})`;
}

async function draw3d(record, box, toggles, legend, chart) {
  const S = makeSurface(record);
  const [nU, nV] = [240, 210];  // 100k triangles
  const viewer = await createViewer(box);
  const positions = grid(S, nU, nV);
  viewer.surface('surface', positions, gridIndex(nU, nV));
  LANDMARKS.forEach((name) => { const m = record.landmarks[name]; if (m) viewer.ring(`ring-${name}`, ring(S, m.height_mm), name); });
  // the order form's points the scan gave off the calf: the foot's (cA, cY, foot length) as
  // markers where the tape lies; the thigh's (cE, cF, cG, above the surface's D) as a tape
  // ring at its height - the circle of the measured girth about the section's centre (the
  // record keeps the girth and the centre, not the section's outline)
  const measured = (chart || []).filter((p) => p.at_mm && p.value_mm != null);
  measured.filter((p) => !THIGH_POINTS.includes(p.point))
    .forEach((p) => viewer.marker(`point-${p.point}`, p.at_mm, 0xb45309, 4, `${p.point} ${p.value_mm.toFixed(0)}`));
  measured.filter((p) => THIGH_POINTS.includes(p.point)).forEach((p) => {
    const radius = p.value_mm / (2 * Math.PI);
    const circle = Array.from({ length: 96 }, (_, i) => {
      const a = (2 * Math.PI * i) / 96;
      return [p.at_mm[0] + radius * Math.cos(a), p.at_mm[1] + radius * Math.sin(a), p.at_mm[2]];
    });
    viewer.ring(`point-${p.point}`, circle, `${p.point} ${p.value_mm.toFixed(0)}`, 0xb45309);
  });
  viewer.frameAll();
  const toggle = (id, label, on, change) => {
    const input = h('input', { id, type: 'checkbox', checked: on, onchange: () => change(input.checked) });
    toggles.append(h('label', { for: id }, input, label));
    return input;
  };
  toggle('show-surface', 'Surface', true, (on) => viewer.visible('surface', on));
  let scan;
  try {
    // an imported or population record has no scan: do not ask (a 404 is a console error)
    if (!record.scan_id) throw new Error('no scan');
    scan = await api(`/records/${record.id}/scan-points?limit=20000`);
  } catch (error) {
    toggles.append(h('span', { class: 'muted', text: 'No stored scan for this record.' }));
    return viewer;
  }
  const points = new Float32Array(scan.points.flat());
  // the scale's top is the 95th percentile of the distances (at least 0.5 mm): a few stray
  // points far off would otherwise push every other point to the bottom colour
  const sorted = [...scan.distance_mm].sort((a, b) => a - b);
  const top = Math.max(0.5, sorted.length ? sorted[Math.floor(0.95 * (sorted.length - 1))] : 1);
  const errColours = new Float32Array(scan.distance_mm.flatMap((d) => colour('error', d / top)));
  viewer.points('scan', points, null, 2);
  viewer.visible('scan', false);
  toggle('show-scan', 'Scan points', false, (on) => viewer.visible('scan', on));
  toggle('error-colours', 'Error colours (distance to the scan)', false, (on) => {
    viewer.points('scan', points, on ? errColours : null, on ? 3 : 2);
    document.getElementById('show-scan').checked = true;
    legend.replaceChildren(...(on ? [h('span', { text: '0 mm' }), h('span', { class: 'ramp', id: 'error-ramp' }), h('span', { text: `${top.toFixed(1)} mm or more` }),
      h('span', { class: 'muted', text: `median ${mm(scan.median_distance_mm, 2)} mm over ${scan.n_points} points` })] : []));
    const ramp = document.getElementById('error-ramp');
    if (ramp) ramp.style.background = legendRamp('error');
  });
  return viewer;
}

async function drawProfile(record, box) {
  const d = record.landmarks.D.height_mm;
  const heights = [];
  for (let z = 2; z < d - 1 && heights.length < 200; z += Math.max(2.5, d / 180)) heights.push(+z.toFixed(1));
  const r = await api(`/records/${record.id}/measurements?heights=${heights.join(',')}`);
  box.replaceChildren(h('h2', { text: 'Circumference profile' }), lineChart({ title: 'Girth along the leg',
    series: [{ x: r.heights.map((g) => g.height_mm), y: r.heights.map((g) => g.tape_circumference_mm), label: 'tape girth', color: '#0b62c4' },
      { x: r.heights.map((g) => g.height_mm), y: r.heights.map((g) => g.circumference_mm), label: 'section perimeter', color: '#c2410c', dash: '5 3' }],
    xLabel: 'height above B, mm', yLabel: 'girth, mm' }));
}

// ---------------------------------------------------------------- design form
async function designForm(recordId) {
  const present = presenter();
  const options = (id, values) => h('select', { id }, values.map(([v, t]) => h('option', { value: v, text: t })));
  const kind = options('target-kind', [['class', 'a compression class'], ['explicit', 'explicit targets']]);
  const standard = options('standard', [['RAL', 'RAL-GZ 387'], ['BS', 'BS 6612'], ['AFNOR', 'NF G30-102']]);
  // the classes of each standard (app/geometry/garment/standards.py COMPRESSION_CLASSES)
  const classesOf = { RAL: ['I', 'II', 'III', 'IV'], BS: ['1', '2', '3'], AFNOR: ['1', '2', '3', '4'] };
  const cls = options('compression-class', classesOf.RAL.map((c) => [c, c]));
  cls.value = 'II';
  standard.addEventListener('change', () => {
    const keep = cls.selectedIndex;
    cls.replaceChildren(...classesOf[standard.value].map((c) => h('option', { value: c, text: c })));
    cls.selectedIndex = Math.min(Math.max(keep, 0), cls.options.length - 1);
  });
  const targets = LANDMARKS.map((n) => [h('label', { for: `target-${n}`, text: `Target at ${n}, mmHg` }), h('input', { id: `target-${n}`, type: 'number', step: '0.5', min: 0 })]);
  const fabricKind = options('fabric-kind', [['linear', 'linear: stiffness K'], ['table', 'measured: tension-strain table']]);
  const stiffness = h('input', { id: 'stiffness', type: 'number', step: '0.1', min: 0.1, value: 10 });
  const table = h('textarea', { id: 'fabric-table', placeholder: 'strain, tension N/cm per line\n0.1, 1.2\n0.3, 4.0\n0.6, 9.5' });
  const limit = h('input', { id: 'hot-limit', type: 'number', step: '1', min: 1, value: 60 });
  const toe = options('toe', [['closed', 'closed toe'], ['open', 'open toe']]);
  const stockingType = options('stocking-type', [['AD', 'AD knee-high (to below the knee)'], ['AG', 'AG thigh-high (to the top of the thigh)']]);
  const out = h('div');
  const form = h('form', { class: 'card', onsubmit: async (e) => {
    e.preventDefault();
    const body = { standard: standard.value, hot_spot_limit_mmHg: Number(limit.value), toe: toe.value,
      stocking_type: stockingType.value, fabric: {} };
    if (kind.value === 'class') body.compression_class = cls.value;
    else { body.compression_class = null; body.targets_mmHg = Object.fromEntries(LANDMARKS.map((n) => [n, Number(document.getElementById(`target-${n}`).value)])); }
    if (fabricKind.value === 'linear') body.fabric.stiffness_n_per_cm = Number(stiffness.value);
    else body.fabric.table = table.value.trim().split(/\n+/).map((line) => line.split(/[,;\s]+/).filter(Boolean).map(Number));
    try {
      const design = await api(`/records/${recordId}/designs`, { method: 'POST', json: body });
      location.hash = `#/designs/${design.id}`;
    } catch (error) { out.replaceChildren(problemBox(error)); }
  } },
  h('div', { class: 'grid-half' },
    h('fieldset', {}, h('legend', { text: 'Pressure' }), h('label', { for: 'stocking-type', text: 'Stocking' }), stockingType,
      h('label', { for: 'target-kind', text: 'Design to' }), kind,
      h('label', { for: 'standard', text: 'Standard' }), standard, h('label', { for: 'compression-class', text: 'Class' }), cls, targets),
    h('fieldset', {}, h('legend', { text: 'Fabric' }), h('label', { for: 'fabric-kind', text: 'Fabric model' }), fabricKind,
      h('label', { for: 'stiffness', text: 'Stiffness K, N/cm per unit strain' }), stiffness,
      h('label', { for: 'fabric-table', text: 'Tension-strain table' }), table,
      h('label', { for: 'hot-limit', text: 'Hot spot above, mmHg' }), limit,
      h('label', { for: 'toe', text: 'Toe of the stocking' }), toe)),
  h('button', { class: 'primary', type: 'submit', text: 'Design the stocking' }), out);
  present(h('h1', { text: 'New stocking design' }), h('p', {}, h('a', { href: `#/records/${recordId}`, text: '← back to the record' })), form);
}

// ---------------------------------------------------------------- design result
function pressureChart(design) {
  const spec = design.knitting_spec;
  const lm = design.landmarks;
  const series = [{ x: spec.map((r) => r.height_mm), y: spec.map((r) => r.predicted_mean_mmHg), label: 'predicted mean', color: '#0b62c4' },
    { x: spec.map((r) => r.height_mm), y: spec.map((r) => r.target_mmHg), label: 'target', color: '#888', dash: '4 3' }];
  let band = null;
  const range = design.class?.range_mmHg;
  if (range) {
    const ratio = { B: [1, 1], ...Object.fromEntries(Object.entries(design.gradient_table || {}).map(([k, v]) => [k, v.range])) };
    const xs = LANDMARKS.map((n) => lm[n].height_mm);
    band = { x: xs, lo: LANDMARKS.map((n) => range[0] * (ratio[n]?.[0] ?? 0)), hi: LANDMARKS.map((n) => range[1] * (ratio[n]?.[1] ?? 1)) };
  }
  return lineChart({ title: 'Graduated pressure', series, band, xLabel: 'height above B, mm', yLabel: 'pressure, mmHg' });
}

// the design's verdict (older designs have only "passed": normative checks, no hot spots)
const verdictOf = (design) => design.verdict ?? (design.passed ? 'pass' : 'fail');

function designSummary(design) {
  return h('div', {},
    h('p', {}, h('span', { class: `badge ${verdictOf(design)}`, id: 'design-verdict', 'data-verdict': verdictOf(design), text: verdictOf(design).toUpperCase() }),
      ` ${design.class ? `${design.class.standard} class ${design.class.class} (${design.class.range_mmHg.join('–')} mmHg at B)` : 'explicit targets'}`),
    (design.verdict_reasons?.length ? h('ul', { id: 'verdict-reasons' }, design.verdict_reasons.map((r) => h('li', { text: r }))) : null),
    h('table', { class: 'checks' }, h('tbody', {}, design.checks.map((c) => h('tr', {}, h('td', { text: c.name }),
      h('td', { class: c.pass ? 'good' : (c.normative ? 'bad' : 'warn'), text: c.pass ? 'pass' : (c.normative ? 'fail' : 'outside (advisory)') }))))),
    pressureChart(design));
}

// the order of a design (GET /designs/{id}/order): its size chart, the PDF and the JSON, and
// the points of the form the scan does not give (to be taken by tape before it is sent)
function orderCard(design, charts) {
  const chartSelect = h('select', { id: 'order-chart' }, charts.map((c) => h('option', { value: c.id, text: c.product })));
  const out = h('div', { id: 'order-summary', 'aria-live': 'polite' });
  const path = (format) => `/designs/${design.id}/order?format=${format}&chart=${encodeURIComponent(chartSelect.value)}`;
  const name = `order-${design.id.slice(0, 8)}`;
  return h('div', { class: 'card', id: 'order' }, h('h2', { text: 'Order' }),
    h('p', { class: 'muted', text: `${design.inputs.toe ?? 'closed'} toe, ${design.stocking_type === 'AG' ? 'thigh-high (AG)' : 'knee-high (AD)'}` }),
    h('label', { for: 'order-chart', text: 'Size chart for the ready-to-wear check' }), chartSelect,
    h('div', { class: 'actions' },
      h('button', { class: 'primary', type: 'button', id: 'download-order-pdf', text: 'Download the order (PDF)',
        onclick: () => guarded(() => download(path('pdf'), `${name}.pdf`, 'application/pdf')) }),
      h('button', { class: 'secondary', type: 'button', id: 'download-order-json', text: 'Order as JSON',
        onclick: () => guarded(() => download(path('json'), `${name}.json`)) }),
      h('button', { class: 'secondary', type: 'button', id: 'check-order', text: 'What the order still needs',
        onclick: () => guarded(async () => {
          const order = await api(path('json'));
          const missing = order.measurements.filter((m) => m.needed && m.value_mm == null);
          out.replaceChildren(h('p', { text: `Size: ${order.size_decision.decision.replaceAll('_', ' ')}${order.size_decision.best ? ` (${order.size_decision.best})` : ''}.` }),
            missing.length ? h('p', { class: 'warn', text: `Take by tape before sending: ${missing.map((m) => m.point).join(', ')}.` }) : null,
            h('ul', {}, order.warnings.map((w) => h('li', { text: w }))));
        }) })),
    out);
}

async function designScreen(id) {
  const present = presenter();
  const design = await api(`/designs/${id}`);
  const [record, charts] = await Promise.all([api(`/records/${design.record_id}`), api('/size-charts')]);
  const viewerBox = h('div', { class: 'viewer', id: 'pressure-viewer', 'data-label': 'Local skin pressure on the leg' });
  const legend = h('div', { class: 'legend' });
  const hot = design.hot_spots;
  const hotList = h('div', { class: 'card', id: 'hot-spots' }, h('h2', { text: `Hot spots (above ${design.hot_spot_limit_mmHg} mmHg)` }),
    hot.length ? h('table', {}, h('thead', {}, h('tr', {}, ['height mm', 'side', 'angle°', 'peak mmHg', 'from–to mm'].map((t) => h('th', { text: t })))),
      h('tbody', {}, hot.map((s) => h('tr', {}, h('td', { text: mm(s.height_mm) }), h('td', { text: s.side }), h('td', { text: mm(s.angle_deg, 0) }),
        h('td', { text: mm(s.peak_mmHg) }), h('td', { text: `${mm(s.from_height_mm)}–${mm(s.to_height_mm)}` })))))
      : h('p', { class: 'good', text: 'No hot spot: the local pressure stays under the limit everywhere.' }));
  const columns = ['height_mm', 'target_mmHg', 'predicted_mean_mmHg', 'stretched_circumference_mm', 'strain', 'tension_N_per_cm', 'relaxed_circumference_mm'];
  // the foot and the top band in words above the rows (app/geometry/garment/stocking_ends.py)
  const foot = design.foot, band = design.top_band;
  const ends = [
    foot ? (foot.designed ? `Foot: ${foot.toe} toe, rows at ${foot.points.join(', ')} for B's pressure; ${foot.length_rule}`
      + (foot.knitted_length_mm != null ? ` (${mm(foot.knitted_length_mm, 0)} mm).` : '.') : `Foot: not designed: ${foot.reason}`) : null,
    band ? `Top band: ${band.width_mm} mm wide (${mm(band.from_height_mm, 0)}–${mm(band.to_height_mm, 0)} mm), relaxed circumference `
      + `${mm(band.relaxed_circumference_mm, 0)} mm, ${mm(band.band_mmHg[0])}–${mm(band.band_mmHg[1])} mmHg: nowhere tighter than the graded rows.` : null,
  ].filter(Boolean).map((text) => h('p', { class: 'ends', text }));
  const spec = h('div', { class: 'card' }, h('h2', { text: 'Knitting specification, from the foot to the top' }), ...ends,
    h('button', { class: 'secondary', type: 'button', id: 'download-spec', text: 'Download CSV',
      onclick: () => guarded(() => download(`/designs/${id}/knitting-spec`, `knitting-${id.slice(0, 8)}.csv`)) }),
    h('div', { class: 'scroll' }, h('table', { id: 'knitting-spec' }, h('thead', {}, h('tr', {}, h('th', { text: 'part' }),
      columns.map((c) => h('th', { class: 'num', text: c.replaceAll('_', ' ') })))),
      h('tbody', {}, design.knitting_spec.map((row) => h('tr', { 'data-part': row.part || 'leg' },
        h('td', { text: [row.part || 'leg', row.point || ''].join(' ').trim() }),
        columns.map((c) => h('td', { class: 'num', text: typeof row[c] === 'number' ? row[c].toFixed(c === 'strain' ? 3 : 1) : row[c] }))))))));
  if (!present(h('h1', { text: `Stocking design${design.case_ref ? ` · case ${design.case_ref}` : ''}` }),
    h('p', {}, h('a', { href: `#/records/${design.record_id}`, text: '← back to the record' })),
    h('div', { class: 'grid2' }, h('div', {}, h('div', { class: 'card' }, viewerBox, legend), hotList),
      h('div', {}, h('div', { class: 'card' }, designSummary(design)), orderCard(design, charts))), spec)) return;
  // the pressure map: rings x angles grid in the calf frame (CSV), coloured by local pressure
  const csv = await api(`/designs/${id}/pressure-map?format=csv`, { accept: 'text/csv' });
  const rows = csv.trim().split('\n').slice(1).map((line) => line.split(',').map(Number));
  const heights = [...new Set(rows.map((r) => r[0]))];
  const n = rows.length / heights.length;
  const topP = Math.max(design.hot_spot_limit_mmHg, ...rows.map((r) => r[5]));
  const positions = new Float32Array(rows.length * 3), colours = new Float32Array(rows.length * 3);
  // CSV order: height-major (k, n); the viewer's grid is angle-major (n, k)
  rows.forEach((r, idx) => {
    const k = Math.floor(idx / n), a = idx % n, j = a * heights.length + k;
    positions.set([r[2], r[3], r[4]], j * 3);
    colours.set(colour('pressure', r[5] / topP), j * 3);
  });
  const viewer = await createViewer(viewerBox);
  viewer.surface('pressure', positions, gridIndex(n, heights.length), colours);
  hot.forEach((s, i) => {
    const k = heights.reduce((best, z, idx) => (Math.abs(z - s.height_mm) < Math.abs(heights[best] - s.height_mm) ? idx : best), 0);
    const a = rows.slice(k * n, (k + 1) * n).reduce((best, r, idx, arr) => (Math.abs(r[1] - s.angle_deg) < Math.abs(arr[best][1] - s.angle_deg) ? idx : best), 0);
    const r = rows[k * n + a];
    viewer.marker(`hot-${i}`, [r[2], r[3], r[4]], 0xd00000, 3);
  });
  viewer.frameAll();
  legend.replaceChildren(h('span', { text: '0 mmHg' }), h('span', { class: 'ramp', id: 'pressure-ramp' }), h('span', { text: `${topP.toFixed(0)} mmHg` }),
    hot.length ? h('span', { class: 'bad', text: `● ${hot.length} hot spot${hot.length > 1 ? 's' : ''}` }) : null);
  document.getElementById('pressure-ramp').style.background = legendRamp('pressure');
}

async function twoDesigns(a, b) {
  const present = presenter();
  const [da, db] = await Promise.all([api(`/designs/${a}`), api(`/designs/${b}`)]);
  const column = (d) => h('div', { class: 'card' }, h('h2', {}, h('a', { href: `#/designs/${d.id}`, text: `${d.inputs.standard} ${d.inputs.compression_class ?? 'targets'}, fabric ${d.inputs.fabric.stiffness_n_per_cm ? `K ${d.inputs.fabric.stiffness_n_per_cm} N/cm` : 'table'}` })),
    designSummary(d), h('p', { text: `${d.hot_spots.length} hot spots` }));
  present(h('h1', { text: 'Two designs side by side' }), h('div', { class: 'grid-half' }, column(da), column(db)));
}

// ---------------------------------------------------------------- comparison
async function compareScreen(a, b) {
  const present = presenter();
  const result = await api(`/records/${a}/compare/${b}`);
  const g = result.girths;
  const csv = await api(`/records/${a}/compare/${b}?format=csv`, { accept: 'text/csv' });
  const viewerBox = h('div', { class: 'viewer', id: 'difference-viewer', 'data-label': 'Signed difference between the two records' });
  const legend = h('div', { class: 'legend' });
  const v = result.volume;
  present(h('h1', { text: 'Two records of one leg compared' }),
    h('p', {}, h('a', { href: `#/records/${a}`, text: 'first record' }), ' → ', h('a', { href: `#/records/${b}`, text: 'second record' }), ` (aligned at ${result.align})`),
    h('div', { class: 'grid2' }, h('div', {}, h('div', { class: 'card' }, viewerBox, legend)),
      h('div', { class: 'card' }, h('h2', { text: 'Volume between B and D' }),
        h('p', { id: 'volume-change', text: `${mm(v.a_ml)} ml → ${mm(v.b_ml)} ml: ${v.change_ml >= 0 ? '+' : ''}${mm(v.change_ml)} ml (${v.change_percent >= 0 ? '+' : ''}${mm(v.change_percent, 2)}%)` }),
        lineChart({ title: 'Girth difference (second − first)', series: [{ x: g.map((r) => r.height_mm), y: g.map((r) => r.difference_mm), label: 'difference', color: '#b3261e' }],
          xLabel: `height above ${result.align}, mm`, yLabel: 'mm', zeroLine: true }),
        lineChart({ title: 'Girths', series: [{ x: g.map((r) => r.height_mm), y: g.map((r) => r.girth_a_mm), label: 'first', color: '#0b62c4' },
          { x: g.map((r) => r.height_mm), y: g.map((r) => r.girth_b_mm), label: 'second', color: '#c2410c', dash: '5 3' }], xLabel: `height above ${result.align}, mm`, yLabel: 'tape girth, mm' }))));
  const rows = csv.trim().split('\n').slice(1).map((line) => line.split(',').map((x) => (x === '' ? NaN : Number(x))));
  const top = Math.max(2, ...rows.map((r) => Math.abs(r[4])).filter(Number.isFinite));
  const viewer = await createViewer(viewerBox);
  viewer.points('difference', new Float32Array(rows.flatMap((r) => [r[0], r[1], r[2]])),
    new Float32Array(rows.flatMap((r) => (Number.isFinite(r[4]) ? colour('diverging', 0.5 + 0.5 * r[4] / top) : [0.6, 0.6, 0.6]))), 4);
  viewer.frameAll();
  legend.replaceChildren(h('span', { text: `−${top.toFixed(1)} mm` }), h('span', { class: 'ramp', id: 'diff-ramp' }), h('span', { text: `+${top.toFixed(1)} mm (second outside first)` }));
  document.getElementById('diff-ramp').style.background = legendRamp('diverging');
}

// ---------------------------------------------------------------- routing
async function route() {
  const [path, query = ''] = location.hash.replace(/^#/, '').split('?');
  const parts = path.split('/').filter(Boolean);
  const params = new URLSearchParams(query);
  document.getElementById('nav').hidden = !apiKey.get();
  if (!apiKey.get() && parts[0] !== 'sign-in') { location.hash = '#/sign-in'; return; }
  status('');
  generation += 1;
  await guarded(async () => {
    if (parts[0] === 'sign-in') return signIn();
    if (parts[0] === 'upload') return uploadScreen();
    if (parts[0] === 'records' && parts[1] && parts[2] === 'design') return designForm(parts[1]);
    if (parts[0] === 'records' && parts[1]) return recordScreen(parts[1]);
    if (parts[0] === 'designs' && parts[2] === 'vs') return twoDesigns(parts[1], parts[3]);
    if (parts[0] === 'designs' && parts[1]) return designScreen(parts[1]);
    if (parts[0] === 'compare') return compareScreen(parts[1], parts[2]);
    return recordsScreen(params);
  });
}

document.getElementById('sign-out').addEventListener('click', () => { apiKey.clear(); location.hash = '#/sign-in'; });
window.addEventListener('hashchange', route);
route();
