// Small SVG line charts (no library): series of (x, y), an optional band, labelled axes.
const NS = 'http://www.w3.org/2000/svg';

function el(name, attrs = {}, text) {
  const node = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, v);
  if (text != null) node.textContent = text;
  return node;
}

function ticks(lo, hi, count = 5) {
  const step = Math.pow(10, Math.floor(Math.log10((hi - lo) / count || 1)));
  const nice = [1, 2, 5, 10].map((m) => m * step).find((s) => (hi - lo) / s <= count) || step * 10;
  const out = [];
  for (let t = Math.ceil(lo / nice) * nice; t <= hi + 1e-9; t += nice) out.push(+t.toFixed(6));
  return out;
}

export function lineChart({ title, series, band, xLabel, yLabel, width = 640, height = 300, zeroLine = false }) {
  const m = { l: 56, r: 14, t: 26, b: 40 };
  const xs = series.flatMap((s) => s.x).concat(band ? band.x : []);
  const ys = series.flatMap((s) => s.y).concat(band ? band.lo.concat(band.hi) : []).filter(Number.isFinite);
  let [x0, x1] = [Math.min(...xs), Math.max(...xs)], [y0, y1] = [Math.min(...ys), Math.max(...ys)];
  if (zeroLine) { y0 = Math.min(y0, 0); y1 = Math.max(y1, 0); }
  const pad = (y1 - y0) * 0.08 || 1; y0 -= pad; y1 += pad;
  const X = (x) => m.l + (x - x0) / (x1 - x0 || 1) * (width - m.l - m.r);
  const Y = (y) => height - m.b - (y - y0) / (y1 - y0 || 1) * (height - m.t - m.b);
  const svg = el('svg', { viewBox: `0 0 ${width} ${height}`, class: 'chart', role: 'img', 'aria-label': title });
  svg.append(el('title', {}, title));
  svg.append(el('text', { x: m.l, y: 16, 'font-weight': 600 }, title));
  for (const t of ticks(x0, x1)) {
    svg.append(el('line', { x1: X(t), x2: X(t), y1: m.t, y2: height - m.b, stroke: '#eceff3' }));
    svg.append(el('text', { x: X(t), y: height - m.b + 14, 'text-anchor': 'middle' }, t));
  }
  for (const t of ticks(y0, y1)) {
    svg.append(el('line', { x1: m.l, x2: width - m.r, y1: Y(t), y2: Y(t), stroke: '#eceff3' }));
    svg.append(el('text', { x: m.l - 6, y: Y(t) + 4, 'text-anchor': 'end' }, t));
  }
  svg.append(el('text', { x: (m.l + width - m.r) / 2, y: height - 6, 'text-anchor': 'middle' }, xLabel));
  svg.append(el('text', { x: 12, y: (m.t + height - m.b) / 2, transform: `rotate(-90 12 ${(m.t + height - m.b) / 2})`, 'text-anchor': 'middle' }, yLabel));
  if (band) {
    const top = band.x.map((x, i) => `${X(x)},${Y(band.hi[i])}`);
    const bottom = band.x.map((x, i) => `${X(x)},${Y(band.lo[i])}`).reverse();
    svg.append(el('polygon', { points: top.concat(bottom).join(' '), fill: '#0b62c4', 'fill-opacity': 0.12 }));
  }
  if (zeroLine) svg.append(el('line', { x1: m.l, x2: width - m.r, y1: Y(0), y2: Y(0), stroke: '#888' }));
  series.forEach((s, k) => {
    const d = s.x.map((x, i) => (Number.isFinite(s.y[i]) ? `${X(x)},${Y(s.y[i])}` : null)).filter(Boolean).join(' ');
    svg.append(el('polyline', { points: d, fill: 'none', stroke: s.color, 'stroke-width': 2, 'stroke-dasharray': s.dash || '' }));
    svg.append(el('text', { x: width - m.r - 4, y: m.t + 14 + 14 * k, 'text-anchor': 'end', fill: s.color }, s.label));
  });
  return svg;
}
