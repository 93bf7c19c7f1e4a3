// Generic source of the fast SIFT kernels (sift_fast_kernels.h), included by one translation unit
// per instruction set after it has defined, inside an anonymous namespace, a vector type `V` with:
//   V::N lanes; V::F float vector, V::I int32 vector, V::M lane mask;
//   load/store (unaligned, float and int), load_u8 (N bytes -> floats), set1, seti, iota (0..N-1),
//   add sub mul div fma(a, b, c) = a*b + c (one rounding) min max abs sqrt floor (float result),
//   to_int (exact for integral values, round-half-even otherwise), to_float, int add/mul/sub,
//   gt lt ge le (float, -> M), ilt ige (int, -> M), mand mor, select(m, a, b), iselect,
//   bits(m) (lane i -> bit i), first_lanes(n) (mask of lanes < n), interleave(lo, hi, out)
//   (out[2i] = lo[i], out[2i+1] = hi[i]), transpose8 (8 vectors -> lane l's 8 values at
//   out[aos(l)], contiguous), add8 (8-float add in place).
// Everything here is elementwise or in a fixed order, so every V gives the same bits.
//
// Buffers passed to these kernels are padded: reading or writing up to 2 x 16 floats past the
// last element asked for is allowed (lanes past the end are computed and ignored).

constexpr float kAtanP1 = 0.9997878412794807f * static_cast<float>(180.0 / 3.14159265358979323846);
constexpr float kAtanP3 = -0.3258083974640975f * static_cast<float>(180.0 / 3.14159265358979323846);
constexpr float kAtanP5 = 0.1555786518463281f * static_cast<float>(180.0 / 3.14159265358979323846);
constexpr float kAtanP7 = -0.04432655554792128f * static_cast<float>(180.0 / 3.14159265358979323846);
constexpr float kAtanEps = static_cast<float>(2.220446049250313e-16);  // (float)DBL_EPSILON

// atan2(y, x) in degrees, [0, 360]: OpenCV's polynomial fastAtan2 (max error ~0.01 degree).
inline V::F atanDegV(V::F y, V::F x) {
  const V::F ax = V::abs(x), ay = V::abs(y);
  const V::F c = V::div(V::min(ax, ay), V::add(V::max(ax, ay), V::set1(kAtanEps)));
  const V::F cc = V::mul(c, c);
  V::F a = V::fma(cc, V::set1(kAtanP7), V::set1(kAtanP5));
  a = V::fma(a, cc, V::set1(kAtanP3));
  a = V::fma(a, cc, V::set1(kAtanP1));
  a = V::mul(a, c);
  a = V::select(V::ge(ax, ay), a, V::sub(V::set1(90.f), a));
  const V::F zero = V::set1(0.f);
  a = V::select(V::lt(x, zero), V::sub(V::set1(180.f), a), a);
  a = V::select(V::lt(y, zero), V::sub(V::set1(360.f), a), a);
  return a;
}

// exp(x) for x <= 0 (Cody-Waite reduction, degree-5 polynomial; < 2 ulp on [-87, 0]).
inline V::F expV(V::F x) {
  x = V::max(x, V::set1(-87.f));
  const V::F magic = V::set1(12582912.f);  // 1.5 * 2^23: adding it rounds to nearest even
  const V::F n = V::sub(V::add(V::mul(x, V::set1(1.44269504088896341f)), magic), magic);
  V::F f = V::fma(n, V::set1(-0.693359375f), x);
  f = V::fma(n, V::set1(2.12194440e-4f), f);
  V::F p = V::set1(1.9875691500e-4f);
  p = V::fma(p, f, V::set1(1.3981999507e-3f));
  p = V::fma(p, f, V::set1(8.3334519073e-3f));
  p = V::fma(p, f, V::set1(4.1665795894e-2f));
  p = V::fma(p, f, V::set1(1.6666665459e-1f));
  p = V::fma(p, f, V::set1(5.0000001201e-1f));
  const V::F y = V::add(V::fma(p, V::mul(f, f), f), V::set1(1.f));
  return V::mul(y, V::pow2(V::to_int(n)));
}

// C vectors of the row filter at once (C independent fused multiply-add chains), taps two at a
// time (the loop overhead is shared; each chain's order stays k[0], k[1], ...).
template <int C>
inline void rowFilterVectors(const float* s, float* out, const float* k, int n) {
  constexpr int N = V::N;
  V::F a[C];
  const V::F first = V::set1(k[0]);
  for (int q = 0; q < C; ++q) a[q] = V::mul(V::load(s + q * N), first);
  int j = 1;
  for (; j + 1 < n; j += 2) {
    const V::F k0 = V::set1(k[j]), k1 = V::set1(k[j + 1]);
    for (int q = 0; q < C; ++q) a[q] = V::fma(V::load(s + j + q * N), k0, a[q]);
    for (int q = 0; q < C; ++q) a[q] = V::fma(V::load(s + j + 1 + q * N), k1, a[q]);
  }
  if (j < n) {
    const V::F k0 = V::set1(k[j]);
    for (int q = 0; q < C; ++q) a[q] = V::fma(V::load(s + j + q * N), k0, a[q]);
  }
  for (int q = 0; q < C; ++q) V::store(out + q * N, a[q]);
}

void rowFilter(const float* in, float* out, int width, const float* k, int n) {
  constexpr int N = V::N;
  int x = 0;
  // Eight independent chains keep both FMA pipes busy; the rest of the row in 4, 2, 1 chains.
  for (; x + 8 * N <= width; x += 8 * N) rowFilterVectors<8>(in + x, out + x, k, n);
  if (x + 4 * N <= width) {
    rowFilterVectors<4>(in + x, out + x, k, n);
    x += 4 * N;
  }
  if (x + 2 * N <= width) {
    rowFilterVectors<2>(in + x, out + x, k, n);
    x += 2 * N;
  }
  for (; x < width; x += N) rowFilterVectors<1>(in + x, out + x, k, n);
}

// Output row q (0 <= q < R) from input rows rows[q .. q + 2h] (centre rows[q + h]); R rows at once
// so that each input row, once in L1, serves several outputs. R = 2 (colFilter): fewer
// instructions than 4 (each row pointer is reloaded per tap and output row) or 1.
template <int R>
void colFilterRows(const float* const* rows, float* const* out, int width, const float* kc, int h) {
  constexpr int N = V::N;
  constexpr int X = 8 / R;  // vectors per row and iteration: 8 chains in all
  int x = 0;
  for (; x + X * N <= width; x += X * N) {
    V::F a[R][X];
    const V::F k0 = V::set1(kc[0]);
    for (int q = 0; q < R; ++q)
      for (int v = 0; v < X; ++v) a[q][v] = V::mul(V::load(rows[q + h] + x + v * N), k0);
    for (int j = 1; j <= h; ++j) {
      const V::F kj = V::set1(kc[j]);
      for (int q = 0; q < R; ++q) {
        const float* up = rows[q + h - j] + x;
        const float* dn = rows[q + h + j] + x;
        for (int v = 0; v < X; ++v) a[q][v] = V::fma(V::add(V::load(up + v * N), V::load(dn + v * N)), kj, a[q][v]);
      }
    }
    for (int q = 0; q < R; ++q)
      for (int v = 0; v < X; ++v) V::store(out[q] + x + v * N, a[q][v]);
  }
  for (; x < width; x += N)
    for (int q = 0; q < R; ++q) {
      V::F a = V::mul(V::load(rows[q + h] + x), V::set1(kc[0]));
      for (int j = 1; j <= h; ++j)
        a = V::fma(V::add(V::load(rows[q + h - j] + x), V::load(rows[q + h + j] + x)), V::set1(kc[j]), a);
      V::store(out[q] + x, a);
    }
}

void colFilter(const float* const* rows, float* const* out, int n_out, int width, const float* kc, int h) {
  for (int q = 0; q < n_out;) {
    const int left = n_out - q;
    if (left >= 2) {
      colFilterRows<2>(rows + q, out + q, width, kc, h);
      q += 2;
    } else {
      colFilterRows<1>(rows + q, out + q, width, kc, h);
      q += 1;
    }
  }
}

void upsampleRow(const uint8_t* row0, const uint8_t* row1, float wa, float wb, float* a, float* out,
                 int w, int m0, int m1) {
  constexpr int N = V::N;
  // Vertical blend (exact: multiples of 1/4 below 256) of input columns [m0 - 1, m1] (clamped to
  // the row) into a[m0 - 1 .. m1]; then out[2m] = .25 a[m-1] + .75 a[m], out[2m+1] = .75 a[m] +
  // .25 a[m+1] for m in [m0, m1).
  const V::F va = V::set1(wa), vb = V::set1(wb);
  int m = m0;
  for (; m + N <= m1; m += N)
    V::store(a + m, V::add(V::mul(V::load_u8(row0 + m), va), V::mul(V::load_u8(row1 + m), vb)));
  for (; m < m1; ++m) a[m] = static_cast<float>(row0[m]) * wa + static_cast<float>(row1[m]) * wb;
  const int l = m0 > 0 ? m0 - 1 : 0, r = m1 < w ? m1 : w - 1;
  a[m0 - 1] = static_cast<float>(row0[l]) * wa + static_cast<float>(row1[l]) * wb;
  a[m1] = static_cast<float>(row0[r]) * wa + static_cast<float>(row1[r]) * wb;
  const V::F q = V::set1(0.25f), t = V::set1(0.75f);
  for (m = m0; m < m1; m += N) {
    const V::F am = V::load(a + m), al = V::load(a + m - 1), ar = V::load(a + m + 1);
    V::interleave(V::add(V::mul(al, q), V::mul(am, t)), V::add(V::mul(am, t), V::mul(ar, q)),
                  out + 2 * m);
  }
}

void dogRow(const float* a, const float* b, float* d, float* mx, float* mn, int width) {
  constexpr int N = V::N;
  // The whole row of differences first (d[-1 .. width + N): a and b are padded), then the 3-tap
  // max/min read back from it (the row is long, so the loads at x +- 1 no longer wait on the
  // stores). Aligned from x = 0 (mx[0], mn[0] are not used).
  d[-1] = b[-1] - a[-1];
  for (int x = 0; x < width + N; x += N) V::store(d + x, V::sub(V::load(b + x), V::load(a + x)));
  for (int x = 0; x < width - 1; x += N) {
    const V::F l = V::load(d + x - 1), c = V::load(d + x), r = V::load(d + x + 1);
    V::store(mx + x, V::max(V::max(l, c), r));
    V::store(mn + x, V::min(V::min(l, c), r));
  }
}

int extremaRow(const float* centre, const float* const* mx, const float* const* mn, int c0, int c1,
               float thr, int32_t* cols) {
  constexpr int N = V::N;
  const V::F vthr = V::set1(thr), zero = V::set1(0.f);
  int count = 0;
  for (int x = c0; x < c1; x += N) {
    const V::F v = V::load(centre + x);
    V::F M = V::load(mx[0] + x), m = V::load(mn[0] + x);
    for (int k = 1; k < 9; ++k) {
      M = V::max(M, V::load(mx[k] + x));
      m = V::min(m, V::load(mn[k] + x));
    }
    const V::M hit = V::mand(V::gt(V::abs(v), vthr),
                             V::mor(V::mand(V::gt(v, zero), V::ge(v, M)),
                                    V::mand(V::lt(v, zero), V::le(v, m))));
    uint32_t bits = V::bits(V::mand(hit, V::first_lanes(c1 - x)));
    while (bits) {
      const int lane = __builtin_ctz(bits);
      bits &= bits - 1;
      cols[count++] = x + lane;
    }
  }
  return count;
}

void gradientSpan(const float* p, int stride, float* mag, float* ori, int n) {
  constexpr int N = V::N;
  for (int x = 0; x < n; x += N) {
    const V::F dx = V::sub(V::load(p + x + 1), V::load(p + x - 1));
    const V::F dy = V::sub(V::load(p + x - stride), V::load(p + x + stride));
    V::store(mag + x, V::sqrt(V::fma(dx, dx, V::mul(dy, dy))));
    V::store(ori + x, atanDegV(dy, dx));
  }
}

// OpenCV's orientation histogram, the Gaussian weight exp(-(i^2 + j^2) / (2 sigma^2)) taken as
// g(i) g(j) (g computed once per call; differs from OpenCV's exp32f in the last bits, as any
// exp does). Samples are added in row-major order, as OpenCV does.
void orientationHist(const GradientPatch& p, int radius, float sigma, int n, float* hist, float* gauss) {
  constexpr int N = V::N;
  const float expf_scale = -1.f / (2.f * sigma * sigma);
  for (int b = 0; b < n; ++b) hist[b] = 0.f;
  const int i0 = p.i0 > -radius ? p.i0 : -radius, i1 = p.i1 < radius ? p.i1 : radius;
  const int j0 = p.j0 > -radius ? p.j0 : -radius, j1 = p.j1 < radius ? p.j1 : radius;
  const V::F nd360 = V::set1(n / 360.f), vscale = V::set1(expf_scale), lanesf = V::iota_f();
  const V::I vn = V::seti(n), izero = V::seti(0);
  float* g = gauss + radius + 16;
  for (int k = -radius; k <= radius; k += N) {
    const V::F kf = V::add(V::set1(static_cast<float>(k)), lanesf);
    V::store(g + k, expV(V::mul(V::mul(kf, kf), vscale)));
  }
  alignas(64) int32_t bin_buf[V::N];
  alignas(64) float val_buf[V::N];
  for (int i = i0; i <= i1; ++i) {
    const float* mag = p.mag + static_cast<ptrdiff_t>(i) * p.pitch;
    const float* ori = p.ori + static_cast<ptrdiff_t>(i) * p.pitch;
    const V::F gi = V::set1(g[i]);
    for (int j = j0; j <= j1; j += N) {
      const V::F w = V::mul(gi, V::load(g + j));
      V::I bin = V::to_int(V::mul(nd360, V::load(ori + j)));
      bin = V::iselect(V::ige(bin, vn), V::isub(bin, vn), bin);
      bin = V::iselect(V::ilt(bin, izero), V::iadd(bin, vn), bin);
      V::istore(bin_buf, bin);
      V::store(val_buf, V::mul(w, V::load(mag + j)));
      const int lanes_used = j1 - j + 1 < N ? j1 - j + 1 : N;
      for (int l = 0; l < lanes_used; ++l) hist[bin_buf[l]] += val_buf[l];
    }
  }
}

// The columns [*ja, *jb] (within [j0, j1]) of window row i whose rotated position can fall inside
// the descriptor's 4x4 grid, |r_rot|, |c_rot| < d/2 + 1/2, widened by one sample (the exact test
// decides); false when there are none.
inline bool descriptorRowColumns(int i, float cos_t, float sin_t, int j0, int j1, int* ja, int* jb) {
  const float lim = 0.5f * 4 + 0.5f;
  float lo_j = -1e30f, hi_j = 1e30f;
  auto clip = [&](float a, float b) {  // |a j + b| < lim
    if (a > 1e-12f || a < -1e-12f) {
      float u = (-lim - b) / a, v = (lim - b) / a;
      if (u > v) {
        const float t = u;
        u = v;
        v = t;
      }
      if (u > lo_j) lo_j = u;
      if (v < hi_j) hi_j = v;
    } else if (b >= lim || b <= -lim) {
      lo_j = 1e30f;
    }
  };
  clip(sin_t, static_cast<float>(i) * cos_t);
  clip(cos_t, -static_cast<float>(i) * sin_t);
  if (lo_j > hi_j + 2.f) return false;
  *ja = j0;
  *jb = j1;
  const float fa = __builtin_floorf(lo_j) - 1.f, fb = __builtin_ceilf(hi_j) + 1.f;
  if (fa > static_cast<float>(*ja)) *ja = static_cast<int>(fa);
  if (fb < static_cast<float>(*jb)) *jb = static_cast<int>(fb);
  return *ja <= *jb;
}

void descriptorColumns(int radius, float cos_t, float sin_t, const GradientPatch& p, int* ja, int* jb) {
  const int i0 = p.i0 > -radius ? p.i0 : -radius, i1 = p.i1 < radius ? p.i1 : radius;
  const int j0 = p.j0 > -radius ? p.j0 : -radius, j1 = p.j1 < radius ? p.j1 : radius;
  for (int i = i0; i <= i1; ++i)
    if (!descriptorRowColumns(i, cos_t, sin_t, j0, j1, ja + (i - i0), jb + (i - i0))) ja[i - i0] = 1, jb[i - i0] = 0;
}

// OpenCV's descriptor histogram: trilinear weights of each sample into 2 x 2 cells x 2 of 8
// orientation bins (bin 8 wraps to 0 directly). Two passes over blocks of up to kDescrBlock
// vectors: the vector pass computes the weights of N samples at a time (iterations independent,
// so they overlap) and each sample's slot (see kDescrSlotFloats), then the scatter pass adds
// each sample's 8 weights to its slot with one 8-float add, sample by sample in row-major order.
// The fold then sums the copies and gives each histogram entry its 8 slot terms in a fixed
// order (the same on every path).
void descriptorHist(const GradientPatch& p, int radius, float cos_t, float sin_t, float ori_deg,
                    const DescriptorScratch& s, float* raw) {
  constexpr int N = V::N;
  constexpr int d = 4, n = 8;
  float* const slots = s.slots;
  const float bins_per_rad = n / 360.f;
  const float exp_scale = -1.f / (d * d * 0.5f);
  const int i0 = p.i0 > -radius ? p.i0 : -radius, i1 = p.i1 < radius ? p.i1 : radius;
  const int j0 = p.j0 > -radius ? p.j0 : -radius, j1 = p.j1 < radius ? p.j1 : radius;
  const V::F vcos = V::set1(cos_t), vsin = V::set1(sin_t), lanesf = V::iota_f();
  const V::F half_d = V::set1(static_cast<float>(d / 2)), half = V::set1(0.5f);
  const V::F lo = V::set1(-1.f), hi = V::set1(static_cast<float>(d));
  const V::F vori = V::set1(ori_deg), vbins = V::set1(bins_per_rad);
  const V::F f5 = V::set1(5.f), f6 = V::set1(6.f), vN = V::set1(static_cast<float>(N));
  const V::I seven = V::seti(7), copies = V::seti(kDescrCopies - 1), copy_floats = V::seti(kDescrSlotFloats);
  const V::I slot_floats = V::seti(64), bin_floats = V::seti(8);
  int blocks = 0;
  // The Gaussian weight exp(-(c_rot^2 + r_rot^2) / 8) = g(i) g(j), g(k) = exp(-k^2 / (8 hw^2)).
  float* gw = s.gauss + radius + 16;
  {
    const float g_scale = (cos_t * cos_t + sin_t * sin_t) * exp_scale;
    for (int k = -radius; k <= radius; k += N) {
      const V::F kf = V::add(V::set1(static_cast<float>(k)), lanesf);
      V::store(gw + k, expV(V::mul(V::mul(kf, kf), V::set1(g_scale))));
    }
  }
  auto flush = [&]() {  // the scatter pass over the block
    for (int q = 0; q < blocks; ++q) {
      const float* wbuf = s.weights + q * 8 * N;
      const int32_t* slot = s.index + q * N;  // copy * kDescrSlotFloats + slot offset
      uint32_t bits = s.bits[q];
      if (bits == V::bits(V::first_lanes(N))) {  // all lanes: no bit scan
        for (int l = 0; l < N; ++l) V::add8(slots + slot[l], wbuf + V::aos(l));
        continue;
      }
      while (bits) {
        const int l = __builtin_ctz(bits);
        bits &= bits - 1;
        V::add8(slots + slot[l], wbuf + V::aos(l));
      }
    }
    blocks = 0;
  };
  for (int i = i0; i <= i1; ++i) {
    const float* mag = p.mag + static_cast<ptrdiff_t>(i) * p.pitch;
    const float* ori = p.ori + static_cast<ptrdiff_t>(i) * p.pitch;
    const V::F i_sin = V::set1(static_cast<float>(i) * sin_t);
    const V::F i_cos = V::set1(static_cast<float>(i) * cos_t);
    const V::F gi = V::set1(gw[i]);
    int ja, jb;
    if (!descriptorRowColumns(i, cos_t, sin_t, j0, j1, &ja, &jb)) continue;
    V::F jf = V::add(V::set1(static_cast<float>(ja)), lanesf);
    for (int j = ja; j <= jb; j += N, jf = V::add(jf, vN)) {
      if (blocks == kDescrBlock) flush();
      const V::F c_rot = V::sub(V::mul(jf, vcos), i_sin);
      const V::F r_rot = V::add(V::mul(jf, vsin), i_cos);
      V::F rbin = V::sub(V::add(r_rot, half_d), half);
      V::F cbin = V::sub(V::add(c_rot, half_d), half);
      const V::M inside = V::mand(V::mand(V::gt(rbin, lo), V::lt(rbin, hi)),
                                  V::mand(V::gt(cbin, lo), V::lt(cbin, hi)));
      const uint32_t bits = V::bits(V::mand(inside, V::first_lanes(jb - j + 1)));
      if (!bits) continue;
      const V::F w = V::mul(gi, V::load(gw + j));
      V::F obin = V::mul(V::sub(V::load(ori + j), vori), vbins);
      const V::F m = V::mul(V::load(mag + j), w);
      const V::F r0f = V::floor(rbin), c0f = V::floor(cbin), o0f = V::floor(obin);
      rbin = V::sub(rbin, r0f);
      cbin = V::sub(cbin, c0f);
      obin = V::sub(obin, o0f);
      // o0 in [-8, 8]: & 7 is OpenCV's wrap (o0 < 0: + n; o0 >= n: - n).
      const V::I o0 = V::iand(V::to_int(o0f), seven);
      const V::F v_r1 = V::mul(m, rbin), v_r0 = V::sub(m, v_r1);
      const V::F v_rc11 = V::mul(v_r1, cbin), v_rc10 = V::sub(v_r1, v_rc11);
      const V::F v_rc01 = V::mul(v_r0, cbin), v_rc00 = V::sub(v_r0, v_rc01);
      const V::F v_rco111 = V::mul(v_rc11, obin), v_rco110 = V::sub(v_rc11, v_rco111);
      const V::F v_rco101 = V::mul(v_rc10, obin), v_rco100 = V::sub(v_rc10, v_rco101);
      const V::F v_rco011 = V::mul(v_rc01, obin), v_rco010 = V::sub(v_rc01, v_rco011);
      const V::F v_rco001 = V::mul(v_rc00, obin), v_rco000 = V::sub(v_rc00, v_rco001);
      // Slot (rr * 5 + cc) * 64 + o0 * 8, rr * 5 + cc = (r0 + 1) * 5 + c0 + 1 (exact small integers).
      const V::F cell = V::fma(r0f, f5, V::add(c0f, f6));
      const V::I copy = V::iand(V::to_int(jf), copies);
      V::istore(s.index + blocks * N, V::iadd(V::iadd(V::imul(V::to_int(cell), slot_floats), V::imul(o0, bin_floats)),
                                              V::imul(copy, copy_floats)));
      V::transpose8(v_rco000, v_rco001, v_rco010, v_rco011, v_rco100, v_rco101, v_rco110, v_rco111,
                    s.weights + blocks * 8 * N);
      s.bits[blocks++] = bits;
    }
  }
  flush();
  const V::F zero = V::set1(0.f);
  float* const sum = s.sum;
  for (int b = 0; b < kDescrSlotFloats; b += N) {
    V::F t = V::load(slots + b);
    V::store(slots + b, zero);
    for (int c = 1; c < kDescrCopies; ++c) {
      t = V::add(t, V::load(slots + c * kDescrSlotFloats + b));
      V::store(slots + c * kDescrSlotFloats + b, zero);
    }
    V::store(sum + b, t);
  }
  // Cell (rr, cc) = (r + 1, c + 1), bin b: the terms k = dr * 4 + dc * 2 + do of the slots
  // (rr - dr, cc - dc, (b - do) mod 8), added in k order.
  for (int r = 0; r < d; ++r)
    for (int c = 0; c < d; ++c)
      for (int bin = 0; bin < n; ++bin) {
        float acc = 0.f;
        for (int k = 0; k < 8; ++k) {
          const int dr = k >> 2, dc = (k >> 1) & 1, dob = k & 1;
          acc += sum[(((r + 1 - dr) * 5 + (c + 1 - dc)) * 8 + ((bin - dob) & 7)) * 8 + k];
        }
        raw[(r * d + c) * n + bin] = acc;
      }
}

// OpenCV's orientation histogram smoothing: hist[i] = (t[i-2] + t[i+2]) / 16 + (t[i-1] + t[i+1])
// * 4 / 16 + t[i] * 6 / 16 (fused multiply-adds, innermost first), t = temp with temp[-2..-1] and
// temp[n..n+1] the wrapped bins.
void orientationSmooth(const float* temp, float* hist, int n) {
  for (int i = 0; i < n; ++i)
    hist[i] = __builtin_fmaf(temp[i - 2] + temp[i + 2], 1.f / 16.f,
                             __builtin_fmaf(temp[i - 1] + temp[i + 1], 4.f / 16.f, temp[i] * (6.f / 16.f)));
}

// OpenCV's descriptor normalisation: its squared norm as 16 partial sums (entry b into sum b mod
// 16, fused multiply-adds) added in order, entries clipped at 0.2 of the norm, the clipped norm
// (serial fused multiply-adds), then round(v * 512 / norm) clamped to 0..255. raw is clipped in
// place.
void descriptorFinish(float* raw, float* out) {
  constexpr int N = V::N;
  constexpr int kLen = 128;
  float part[16];
  for (int l = 0; l < 16; l += N) {
    V::F acc = V::set1(0.f);
    for (int b = 0; b < kLen; b += 16) acc = V::fma(V::load(raw + b + l), V::load(raw + b + l), acc);
    V::store(part + l, acc);
  }
  float nrm2 = 0;
  for (int l = 0; l < 16; ++l) nrm2 += part[l];
  const float thr = __builtin_sqrtf(nrm2) * 0.2f;
  nrm2 = 0;
  for (int b = 0; b < kLen; ++b) {
    const float v = raw[b] < thr ? raw[b] : thr;
    raw[b] = v;
    nrm2 = __builtin_fmaf(v, v, nrm2);
  }
  const float root = __builtin_sqrtf(nrm2);
  const float scale = 512.f / (root > 1.1920929e-07f ? root : 1.1920929e-07f);  // FLT_EPSILON
  const V::F vs = V::set1(scale), lo = V::set1(0.f), hi = V::set1(255.f);
  for (int b = 0; b < kLen; b += N)
    V::store(out + b, V::min(V::max(V::to_float(V::to_int(V::mul(V::load(raw + b), vs))), lo), hi));
}

const Kernels kTable = {kIsaName,        rowFilter,         colFilter,         upsampleRow,
                        dogRow,          extremaRow,        gradientSpan,      orientationHist,
                        orientationSmooth, descriptorColumns, descriptorHist, descriptorFinish};
