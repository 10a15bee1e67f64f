// Evaluation of the record's NURBS surface in the browser, from its stored control net,
// weights and knot vectors (The NURBS Book A2.1 span search, A2.2 basis functions,
// A4.3 rational surface point).  Calf frame, mm.

function findSpan(knots, p, n, t) {
  if (t >= knots[n]) return n - 1;
  if (t <= knots[p]) return p;
  let lo = p, hi = n;
  while (hi - lo > 1) {
    const mid = (lo + hi) >> 1;
    if (t < knots[mid]) hi = mid; else lo = mid;
  }
  return lo;
}

function basis(knots, p, span, t) {
  const N = new Float64Array(p + 1), left = new Float64Array(p + 1), right = new Float64Array(p + 1);
  N[0] = 1;
  for (let j = 1; j <= p; j++) {
    left[j] = t - knots[span + 1 - j];
    right[j] = knots[span + j] - t;
    let saved = 0;
    for (let r = 0; r < j; r++) {
      const temp = N[r] / (right[r + 1] + left[j - r]);
      N[r] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    N[j] = saved;
  }
  return N;
}

export function makeSurface(record) {
  const s = record.surface;
  const nu = s.control_points.length, nv = s.control_points[0].length;
  const hw = new Float64Array(nu * nv * 4);
  for (let i = 0; i < nu; i++) for (let j = 0; j < nv; j++) {
    const w = s.weights[i][j], c = s.control_points[i][j], k = (i * nv + j) * 4;
    hw[k] = c[0] * w; hw[k + 1] = c[1] * w; hw[k + 2] = c[2] * w; hw[k + 3] = w;
  }
  return { p: s.degree_u, q: s.degree_v, ku: s.knots_u, kv: s.knots_v, nu, nv, hw,
           u0: s.knots_u[s.degree_u], u1: s.knots_u[nu], v0: s.knots_v[s.degree_v], v1: s.knots_v[nv] };
}

export function point(S, u, v, out = [0, 0, 0]) {
  const su = findSpan(S.ku, S.p, S.nu, u), sv = findSpan(S.kv, S.q, S.nv, v);
  const Nu = basis(S.ku, S.p, su, u), Nv = basis(S.kv, S.q, sv, v);
  let x = 0, y = 0, z = 0, w = 0;
  for (let a = 0; a <= S.p; a++) {
    const row = (su - S.p + a) * S.nv;
    for (let b = 0; b <= S.q; b++) {
      const k = (row + sv - S.q + b) * 4, f = Nu[a] * Nv[b];
      x += f * S.hw[k]; y += f * S.hw[k + 1]; z += f * S.hw[k + 2]; w += f * S.hw[k + 3];
    }
  }
  out[0] = x / w; out[1] = y / w; out[2] = z / w;
  return out;
}

// (nU x nV) grid, u periodic (end excluded), v from end to end: Float32Array positions
export function grid(S, nU, nV) {
  const positions = new Float32Array(nU * nV * 3), p = [0, 0, 0];
  for (let i = 0; i < nU; i++) {
    const u = S.u0 + (S.u1 - S.u0) * i / nU;
    for (let j = 0; j < nV; j++) {
      point(S, u, S.v0 + (S.v1 - S.v0) * j / (nV - 1), p);
      positions.set(p, (i * nV + j) * 3);
    }
  }
  return positions;
}

export function gridIndex(nU, nV) {
  const index = new Uint32Array(nU * (nV - 1) * 6);
  let k = 0;
  for (let i = 0; i < nU; i++) {
    const i1 = (i + 1) % nU;
    for (let j = 0; j < nV - 1; j++) {
      const a = i * nV + j, b = i1 * nV + j;
      index[k++] = a; index[k++] = b; index[k++] = b + 1;
      index[k++] = a; index[k++] = b + 1; index[k++] = a + 1;
    }
  }
  return index;
}

// the ring z = height: for each of n u values, v found by bisection (z rises along v)
export function ring(S, height, n = 180) {
  const out = [], p = [0, 0, 0];
  for (let i = 0; i < n; i++) {
    const u = S.u0 + (S.u1 - S.u0) * i / n;
    let lo = S.v0, hi = S.v1;
    for (let it = 0; it < 40; it++) {
      const mid = 0.5 * (lo + hi);
      if (point(S, u, mid, p)[2] < height) lo = mid; else hi = mid;
    }
    out.push(point(S, u, 0.5 * (lo + hi), [0, 0, 0]));
  }
  return out;
}
