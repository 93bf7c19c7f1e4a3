// Generic source of the fast SIFT kernels (sift_fast_kernels.h), included by one translation unit
// per instruction set after it has defined, inside an anonymous namespace, a vector type `V` with:
//   V::N lanes; V::F float vector, V::I int32 vector, V::M lane mask;
//   load/store (unaligned, float and int), load_u8 (N bytes -> floats), set1, seti, iota (0..N-1),
//   add sub mul div fma(a, b, c) = a*b + c (one rounding) min max abs sqrt floor (float result),
//   to_int (exact for integral values, round-half-even otherwise), to_float, int add/mul/sub,
//   gt lt ge le (float, -> M), ilt ige (int, -> M), mand mor, select(m, a, b), iselect,
//   bits(m) (lane i -> bit i), first_lanes(n) (mask of lanes < n), interleave(lo, hi, out)
//   (out[2i] = lo[i], out[2i+1] = hi[i]).
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

void rowFilter(const float* in, float* out, int width, const float* k, int n) {
  constexpr int N = V::N;
  int x = 0;
  for (; x + 4 * N <= width; x += 4 * N) {
    V::F a0 = V::set1(0.f), a1 = a0, a2 = a0, a3 = a0;
    const float* s = in + x;
    for (int j = 0; j < n; ++j) {
      const V::F kj = V::set1(k[j]);
      a0 = V::fma(V::load(s + j), kj, a0);
      a1 = V::fma(V::load(s + j + N), kj, a1);
      a2 = V::fma(V::load(s + j + 2 * N), kj, a2);
      a3 = V::fma(V::load(s + j + 3 * N), kj, a3);
    }
    V::store(out + x, a0);
    V::store(out + x + N, a1);
    V::store(out + x + 2 * N, a2);
    V::store(out + x + 3 * N, a3);
  }
  for (; x < width; x += N) {
    V::F a = V::set1(0.f);
    for (int j = 0; j < n; ++j) a = V::fma(V::load(in + x + j), V::set1(k[j]), a);
    V::store(out + x, a);
  }
}

void colFilter(const float* const* rows, float* out, int width, const float* kc, int h) {
  constexpr int N = V::N;
  const float* centre = rows[h];
  int x = 0;
  for (; x + 4 * N <= width; x += 4 * N) {
    const V::F k0 = V::set1(kc[0]);
    const float* c = centre + x;
    V::F a0 = V::mul(V::load(c), k0), a1 = V::mul(V::load(c + N), k0);
    V::F a2 = V::mul(V::load(c + 2 * N), k0), a3 = V::mul(V::load(c + 3 * N), k0);
    for (int j = 1; j <= h; ++j) {
      const float* up = rows[h - j] + x;
      const float* dn = rows[h + j] + x;
      const V::F kj = V::set1(kc[j]);
      a0 = V::fma(V::add(V::load(up), V::load(dn)), kj, a0);
      a1 = V::fma(V::add(V::load(up + N), V::load(dn + N)), kj, a1);
      a2 = V::fma(V::add(V::load(up + 2 * N), V::load(dn + 2 * N)), kj, a2);
      a3 = V::fma(V::add(V::load(up + 3 * N), V::load(dn + 3 * N)), kj, a3);
    }
    V::store(out + x, a0);
    V::store(out + x + N, a1);
    V::store(out + x + 2 * N, a2);
    V::store(out + x + 3 * N, a3);
  }
  for (; x < width; x += N) {
    V::F a = V::mul(V::load(centre + x), V::set1(kc[0]));
    for (int j = 1; j <= h; ++j)
      a = V::fma(V::add(V::load(rows[h - j] + x), V::load(rows[h + j] + x)), V::set1(kc[j]), a);
    V::store(out + x, a);
  }
}

void upsampleRow(const uint8_t* row0, const uint8_t* row1, float wa, float wb, float* a, float* out,
                 int w) {
  constexpr int N = V::N;
  // Vertical blend (exact: multiples of 1/4 below 256) into a[0..w), a[-1] = a[0], a[w] = a[w-1].
  const V::F va = V::set1(wa), vb = V::set1(wb);
  int m = 0;
  for (; m + N <= w; m += N)
    V::store(a + m, V::add(V::mul(V::load_u8(row0 + m), va), V::mul(V::load_u8(row1 + m), vb)));
  for (; m < w; ++m) a[m] = static_cast<float>(row0[m]) * wa + static_cast<float>(row1[m]) * wb;
  a[-1] = a[0];
  a[w] = a[w - 1];
  // out[2m] = .25 a[m-1] + .75 a[m], out[2m+1] = .75 a[m] + .25 a[m+1].
  const V::F q = V::set1(0.25f), t = V::set1(0.75f);
  for (m = 0; m < w; m += N) {
    const V::F am = V::load(a + m), al = V::load(a + m - 1), ar = V::load(a + m + 1);
    V::interleave(V::add(V::mul(al, q), V::mul(am, t)), V::add(V::mul(am, t), V::mul(ar, q)),
                  out + 2 * m);
  }
}

void dogRow(const float* a, const float* b, float* d, float* mx, float* mn, int width) {
  constexpr int N = V::N;
  for (int x = 0; x < width; x += N) V::store(d + x, V::sub(V::load(b + x), V::load(a + x)));
  for (int x = 1; x < width - 1; x += N) {
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

void gradientRows(const float* img, int stride, float* mag, float* ori, int y0, int y1, int x0, int x1) {
  constexpr int N = V::N;
  for (int y = y0; y < y1; ++y) {
    const size_t o = static_cast<size_t>(y) * stride;
    const float* row = img + o;
    const float* up = row - stride;
    const float* dn = row + stride;
    for (int x = x0; x < x1; x += N) {
      const V::F dx = V::sub(V::load(row + x + 1), V::load(row + x - 1));
      const V::F dy = V::sub(V::load(up + x), V::load(dn + x));
      V::store(mag + o + x, V::sqrt(V::fma(dx, dx, V::mul(dy, dy))));
      V::store(ori + o + x, atanDegV(dy, dx));
    }
  }
}

void orientationHist(const GradientPatch& p, int radius, float sigma, int n, float* hist) {
  constexpr int N = V::N;
  const float expf_scale = -1.f / (2.f * sigma * sigma);
  for (int b = 0; b < n; ++b) hist[b] = 0.f;
  const int i0 = p.i0 > -radius ? p.i0 : -radius, i1 = p.i1 < radius ? p.i1 : radius;
  const int j0 = p.j0 > -radius ? p.j0 : -radius, j1 = p.j1 < radius ? p.j1 : radius;
  const V::F nd360 = V::set1(n / 360.f), vscale = V::set1(expf_scale);
  const V::I vn = V::seti(n), izero = V::seti(0), lanes = V::iota_i();
  alignas(64) int32_t bin_buf[V::N];
  alignas(64) float val_buf[V::N];
  for (int i = i0; i <= i1; ++i) {
    const float* mag = p.mag + static_cast<ptrdiff_t>(i) * p.pitch;
    const float* ori = p.ori + static_cast<ptrdiff_t>(i) * p.pitch;
    for (int j = j0; j <= j1; j += N) {
      const V::I jj = V::iadd(V::seti(j), lanes);
      const V::I d2 = V::iadd(V::seti(i * i), V::imul(jj, jj));
      const V::F w = expV(V::mul(V::to_float(d2), vscale));
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

// OpenCV's descriptor histogram: trilinear weights of each sample into 2 x 2 cells x 2 of 8
// orientation bins. The per-sample weights are computed N samples at a time, then added sample
// by sample (row-major order) into one of kDescrCopies interleaved histogram copies (sample k
// into copy k mod kDescrCopies, so that consecutive samples do not wait on each other's stores);
// the copies are summed at the end. Orientation bin 8 wraps to 0 directly.
void descriptorHist(const GradientPatch& p, int radius, float cos_t, float sin_t, float ori_deg,
                    const DescriptorScratch& s, float* hist) {
  constexpr int N = V::N;
  constexpr int d = 4, n = 8;
  for (int b = 0; b < kDescrCopies * kDescrCells * n; ++b) hist[b] = 0.f;
  const float bins_per_rad = n / 360.f;
  const float exp_scale = -1.f / (d * d * 0.5f);
  const int i0 = p.i0 > -radius ? p.i0 : -radius, i1 = p.i1 < radius ? p.i1 : radius;
  const int j0 = p.j0 > -radius ? p.j0 : -radius, j1 = p.j1 < radius ? p.j1 : radius;
  const V::F vcos = V::set1(cos_t), vsin = V::set1(sin_t), lanesf = V::iota_f();
  const V::F half_d = V::set1(static_cast<float>(d / 2)), half = V::set1(0.5f);
  const V::F lo = V::set1(-1.f), hi = V::set1(static_cast<float>(d));
  const V::F vori = V::set1(ori_deg), vbins = V::set1(bins_per_rad), vexp = V::set1(exp_scale);
  const V::I vn = V::seti(n), izero = V::seti(0), one = V::seti(1), dp2 = V::seti(d + 2);
  float* wbuf = s.weights;       // the 8 weights of each sample, V::transpose8's layout
  int32_t* cbuf = s.index;       // 8 x cell index (r0 + 1) * (d + 2) + c0 + 1 of each lane
  int32_t* obuf = s.index + N;   // V::cell_table_offset(o0) of each lane
  int sample = 0;
  for (int i = i0; i <= i1; ++i) {
    const float* mag = p.mag + static_cast<ptrdiff_t>(i) * p.pitch;
    const float* ori = p.ori + static_cast<ptrdiff_t>(i) * p.pitch;
    const V::F i_sin = V::set1(static_cast<float>(i) * sin_t);
    const V::F i_cos = V::set1(static_cast<float>(i) * cos_t);
    // Columns whose rotated position can fall inside the 4x4 grid, |r_rot|, |c_rot| < d/2 + 1/2,
    // widened by one sample (the exact test below decides).
    int ja = j0, jb = j1;
    {
      const float lim = 0.5f * d + 0.5f;
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
      if (lo_j > hi_j + 2.f) continue;
      const float fa = __builtin_floorf(lo_j) - 1.f, fb = __builtin_ceilf(hi_j) + 1.f;
      if (fa > static_cast<float>(ja)) ja = static_cast<int>(fa);
      if (fb < static_cast<float>(jb)) jb = static_cast<int>(fb);
      if (ja > jb) continue;
    }
    for (int j = ja; j <= jb; j += N) {
      const V::F jf = V::add(V::set1(static_cast<float>(j)), lanesf);
      const V::F c_rot = V::sub(V::mul(jf, vcos), i_sin);
      const V::F r_rot = V::add(V::mul(jf, vsin), i_cos);
      V::F rbin = V::sub(V::add(r_rot, half_d), half);
      V::F cbin = V::sub(V::add(c_rot, half_d), half);
      const V::M inside = V::mand(V::mand(V::gt(rbin, lo), V::lt(rbin, hi)),
                                  V::mand(V::gt(cbin, lo), V::lt(cbin, hi)));
      uint32_t bits = V::bits(V::mand(inside, V::first_lanes(jb - j + 1)));
      if (!bits) continue;
      const V::F w = expV(V::mul(V::add(V::mul(c_rot, c_rot), V::mul(r_rot, r_rot)), vexp));
      V::F obin = V::mul(V::sub(V::load(ori + j), vori), vbins);
      const V::F m = V::mul(V::load(mag + j), w);
      const V::F r0f = V::floor(rbin), c0f = V::floor(cbin), o0f = V::floor(obin);
      rbin = V::sub(rbin, r0f);
      cbin = V::sub(cbin, c0f);
      obin = V::sub(obin, o0f);
      V::I o0 = V::to_int(o0f);
      o0 = V::iselect(V::ilt(o0, izero), V::iadd(o0, vn), o0);
      o0 = V::iselect(V::ige(o0, vn), V::isub(o0, vn), o0);
      const V::F v_r1 = V::mul(m, rbin), v_r0 = V::sub(m, v_r1);
      const V::F v_rc11 = V::mul(v_r1, cbin), v_rc10 = V::sub(v_r1, v_rc11);
      const V::F v_rc01 = V::mul(v_r0, cbin), v_rc00 = V::sub(v_r0, v_rc01);
      const V::F v_rco111 = V::mul(v_rc11, obin), v_rco110 = V::sub(v_rc11, v_rco111);
      const V::F v_rco101 = V::mul(v_rc10, obin), v_rco100 = V::sub(v_rc10, v_rco101);
      const V::F v_rco011 = V::mul(v_rc01, obin), v_rco010 = V::sub(v_rc01, v_rco011);
      const V::F v_rco001 = V::mul(v_rc00, obin), v_rco000 = V::sub(v_rc00, v_rco001);
      V::istore(cbuf, V::imul(V::iadd(V::imul(V::iadd(V::to_int(r0f), one), dp2), V::iadd(V::to_int(c0f), one)),
                              V::seti(n)));
      V::istore(obuf, V::cell_table_offset(o0));
      V::transpose8(v_rco000, v_rco001, v_rco010, v_rco011, v_rco100, v_rco101, v_rco110, v_rco111, wbuf);
      while (bits) {
        const int l = __builtin_ctz(bits);
        bits &= bits - 1;
        float* h = hist + (sample++ & (kDescrCopies - 1)) * (kDescrCells * n) + cbuf[l];
        V::add_sample(h, wbuf + V::aos_lo(l), wbuf + V::aos_hi(l), obuf[l]);
      }
    }
  }
  for (int c = 1; c < kDescrCopies; ++c)
    for (int b = 0; b < kDescrCells * n; b += N)
      V::store(hist + b, V::add(V::load(hist + b), V::load(hist + c * kDescrCells * n + b)));
}

const Kernels kTable = {kIsaName,   rowFilter,    colFilter,       upsampleRow,   dogRow,
                        extremaRow, gradientRows, orientationHist, descriptorHist};
