// The AVX2 ground sampler (ground.h): built only on x86-64 with AUTODRIVE_RENDER_AVX2 on; its
// functions carry their own target attributes, so the rest of the build needs no -mavx2, and
// run only where the CPU has AVX2 and FMA (`Avx2SamplerAvailable`).
#include <immintrin.h>

#include <bit>
#include <cstring>

#include "vehicle_sim/render/ground.h"

namespace autodrive::vehicle_sim::internal {

namespace {

// One pixel of the ground (the same arithmetic as the AVX2 sampler, for the rows' tails).
inline std::uint32_t GroundPixel(const GroundFrame& f, float x, float y) {
  const float dz = f.r20 * x + f.r21 * y + f.r22;
  if (!(dz < f.min_dz)) return f.walls;
  const float inv = -1.0f / dz;
  const float t = f.height * inv;
  const float gx = f.ccx + t * (f.r00 * x + f.r01 * y + f.r02);
  const float gy = f.ccy + t * (f.r10 * x + f.r11 * y + f.r12);
  const float area = f.a_num * inv * inv * inv;
  int level = 0;
  for (int k = 1; k < 8; ++k) level += area >= f.thresholds[static_cast<std::size_t>(k)] ? 1 : 0;
  const float scale = std::bit_cast<float>((127 - level) << 23);
  const float ox = level > 0 ? f.W0 - 0.5f : -0.5f;
  const float oy = level > 0 ? f.H0 - 2.0f * f.H0 * scale - 0.5f : -0.5f;
  const float uu = std::min(std::max((gx - f.x0) * f.inv_texel * scale, 0.5f), f.W0 * scale - 0.5f);
  const float vv = std::min(std::max((f.y1 - gy) * f.inv_texel * scale, 0.5f), f.H0 * scale - 0.5f);
  const float ax = ox + uu, ay = oy + vv;
  const int i = static_cast<int>(ax), j = static_cast<int>(ay);
  const auto wu = static_cast<std::uint32_t>((ax - static_cast<float>(i)) * 256.0f);
  const auto wv = static_cast<std::uint32_t>((ay - static_cast<float>(j)) * 256.0f);
  const std::uint32_t* p = f.atlas + static_cast<std::ptrdiff_t>(j) * f.stride + i;
  const std::uint32_t c00 = p[0], c01 = p[1], c10 = p[f.stride], c11 = p[f.stride + 1];
  const std::uint32_t w11 = (wu * wv) >> 8, w01 = wu - w11, w10 = wv - w11;
  const std::uint32_t w00 = 256 - wu - wv + w11;
  const std::uint32_t rb = ((c00 & 0xff00ffu) * w00 + (c01 & 0xff00ffu) * w01 +
                            (c10 & 0xff00ffu) * w10 + (c11 & 0xff00ffu) * w11) >>
                           8;
  const std::uint32_t g = ((c00 & 0xff00u) * w00 + (c01 & 0xff00u) * w01 + (c10 & 0xff00u) * w10 +
                           (c11 & 0xff00u) * w11) >>
                          8;
  return (rb & 0xff00ffu) | (g & 0xff00u);
}

// The bilinear blend of four texels' channels under `mask` (R and B, or G, each in 16 bits of
// the 32-bit lanes), weights in 1/256.
__attribute__((target("avx2,fma"))) inline __m256i Blend4(__m256i c00, __m256i c01, __m256i c10,
                                                          __m256i c11, __m256i w00, __m256i w01,
                                                          __m256i w10, __m256i w11, __m256i mask) {
  __m256i sum = _mm256_mullo_epi32(_mm256_and_si256(c00, mask), w00);
  sum = _mm256_add_epi32(sum, _mm256_mullo_epi32(_mm256_and_si256(c01, mask), w01));
  sum = _mm256_add_epi32(sum, _mm256_mullo_epi32(_mm256_and_si256(c10, mask), w10));
  sum = _mm256_add_epi32(sum, _mm256_mullo_epi32(_mm256_and_si256(c11, mask), w11));
  return _mm256_and_si256(_mm256_srli_epi32(sum, 8), mask);
}

// The 32-bit lanes 0 and 2 (or 1 and 3) of each 64-bit pair of p and q: p0 p2 q0 q2 | p4 p6 q4 q6.
__attribute__((target("avx2,fma"))) inline __m256i EvenLanes(__m256i p, __m256i q) {
  return _mm256_castps_si256(
      _mm256_shuffle_ps(_mm256_castsi256_ps(p), _mm256_castsi256_ps(q), _MM_SHUFFLE(2, 0, 2, 0)));
}
__attribute__((target("avx2,fma"))) inline __m256i OddLanes(__m256i p, __m256i q) {
  return _mm256_castps_si256(
      _mm256_shuffle_ps(_mm256_castsi256_ps(p), _mm256_castsi256_ps(q), _MM_SHUFFLE(3, 1, 3, 1)));
}

}  // namespace

// A row of the ground, 8 pixels at a time with AVX2 (the bilinear texels loaded in pairs), the tail
// one by one. `xs`, `ys`: the row's undistorted coordinates (ys null: all `y`).
__attribute__((target("avx2,fma"))) void GroundRowAvx2(const GroundFrame& f, const float* xs,
                                                       const float* ys, float y, int width,
                                                       std::uint8_t* out) {
  const __m256 r00 = _mm256_set1_ps(f.r00), r01 = _mm256_set1_ps(f.r01),
               r02 = _mm256_set1_ps(f.r02);
  const __m256 r10 = _mm256_set1_ps(f.r10), r11 = _mm256_set1_ps(f.r11),
               r12 = _mm256_set1_ps(f.r12);
  const __m256 r20 = _mm256_set1_ps(f.r20), r21 = _mm256_set1_ps(f.r21),
               r22 = _mm256_set1_ps(f.r22);
  const __m256 ccx = _mm256_set1_ps(f.ccx), ccy = _mm256_set1_ps(f.ccy);
  const __m256 height = _mm256_set1_ps(f.height), min_dz = _mm256_set1_ps(f.min_dz);
  const __m256 a_num = _mm256_set1_ps(f.a_num), minus1 = _mm256_set1_ps(-1.0f);
  const __m256 x0 = _mm256_set1_ps(f.x0), y1 = _mm256_set1_ps(f.y1);
  const __m256 inv_texel = _mm256_set1_ps(f.inv_texel);
  const __m256 W0 = _mm256_set1_ps(f.W0), H0 = _mm256_set1_ps(f.H0);
  const __m256 half = _mm256_set1_ps(0.5f), k256 = _mm256_set1_ps(256.0f);
  const __m256 w0_edge = _mm256_set1_ps(f.W0 - 0.5f), minus_half = _mm256_set1_ps(-0.5f);
  const __m256i zero = _mm256_setzero_si256(), bias = _mm256_set1_epi32(127);
  const __m256i stride = _mm256_set1_epi32(f.stride);
  const __m256i rb_mask = _mm256_set1_epi32(0xff00ff), g_mask = _mm256_set1_epi32(0xff00);
  const __m256i k256i = _mm256_set1_epi32(256);
  const __m256i walls = _mm256_set1_epi32(static_cast<int>(f.walls));
  __m256 thresholds[8];
  for (std::size_t k = 1; k < 8; ++k) thresholds[k] = _mm256_set1_ps(f.thresholds[k]);
  const auto* atlas = reinterpret_cast<const int*>(f.atlas);
  // RGBX RGBX RGBX RGBX -> RGBRGBRGBRGB in each 128-bit half.
  const __m128i pack = _mm_setr_epi8(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1);
  const __m256i order = _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7);  // its own inverse
  int u = 0;
  for (; u + 8 <= width; u += 8) {
    const __m256 x = _mm256_loadu_ps(xs + u);
    const __m256 yv = ys != nullptr ? _mm256_loadu_ps(ys + u) : _mm256_set1_ps(y);
    const __m256 dz = _mm256_fmadd_ps(r20, x, _mm256_fmadd_ps(r21, yv, r22));
    const __m256 hit = _mm256_cmp_ps(dz, min_dz, _CMP_LT_OQ);
    if (_mm256_movemask_ps(hit) == 0) {
      // Eight rays over the horizon (the sky of an on-board camera): the walls, no texels.
      const __m128i w = _mm_shuffle_epi8(_mm256_castsi256_si128(walls), pack);
      std::memcpy(out + 3 * u, &w, 12);
      std::memcpy(out + 3 * u + 12, &w, 12);
      continue;
    }
    const __m256 inv = _mm256_div_ps(minus1, _mm256_blendv_ps(minus1, dz, hit));
    const __m256 t = _mm256_mul_ps(height, inv);
    const __m256 gx =
        _mm256_fmadd_ps(t, _mm256_fmadd_ps(r00, x, _mm256_fmadd_ps(r01, yv, r02)), ccx);
    const __m256 gy =
        _mm256_fmadd_ps(t, _mm256_fmadd_ps(r10, x, _mm256_fmadd_ps(r11, yv, r12)), ccy);
    const __m256 area = _mm256_mul_ps(_mm256_mul_ps(a_num, inv), _mm256_mul_ps(inv, inv));
    __m256i level = zero;
    for (std::size_t k = 1; k < 8; ++k) {
      level = _mm256_sub_epi32(level,
                               _mm256_castps_si256(_mm256_cmp_ps(area, thresholds[k], _CMP_GE_OQ)));
    }
    const __m256 scale = _mm256_castsi256_ps(_mm256_slli_epi32(_mm256_sub_epi32(bias, level), 23));
    const __m256 above0 = _mm256_castsi256_ps(_mm256_cmpgt_epi32(level, zero));
    const __m256 ox = _mm256_blendv_ps(minus_half, w0_edge, above0);
    const __m256 oy = _mm256_blendv_ps(
        minus_half, _mm256_sub_ps(_mm256_fnmadd_ps(_mm256_add_ps(H0, H0), scale, H0), half),
        above0);
    const __m256 uu = _mm256_min_ps(
        _mm256_max_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(gx, x0), inv_texel), scale), half),
        _mm256_fmsub_ps(W0, scale, half));
    const __m256 vv = _mm256_min_ps(
        _mm256_max_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(y1, gy), inv_texel), scale), half),
        _mm256_fmsub_ps(H0, scale, half));
    const __m256 ax = _mm256_add_ps(ox, uu), ay = _mm256_add_ps(oy, vv);
    const __m256i i = _mm256_cvttps_epi32(ax), j = _mm256_cvttps_epi32(ay);
    __m256i wu = _mm256_cvttps_epi32(_mm256_mul_ps(_mm256_sub_ps(ax, _mm256_cvtepi32_ps(i)), k256));
    __m256i wv = _mm256_cvttps_epi32(_mm256_mul_ps(_mm256_sub_ps(ay, _mm256_cvtepi32_ps(j)), k256));
    const __m256i idx = _mm256_add_epi32(_mm256_mullo_epi32(j, stride), i);
    // A texel and its right-hand neighbour in one 64-bit load, scalar: as fast as AVX2's
    // gathers here (AMD Zen 5) and far faster where microcode slows gathers down (Intel's
    // Downfall mitigation). Pairs of pixels 0-3 come in a, 4-7 in b; the even and odd
    // lanes of (a, b) are the left and right texels of pixels 0 1 4 5 | 2 3 6 7, the order the
    // weights are put in and the colours are put back from.
    alignas(32) std::int32_t ix[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(ix), idx);
    const std::int64_t s = f.stride;
    const auto at = [&](int k) {
      std::int64_t q;
      std::memcpy(&q, atlas + ix[k], 8);
      return q;
    };
    const auto below = [&](int k) {
      std::int64_t q;
      std::memcpy(&q, atlas + ix[k] + s, 8);
      return q;
    };
    const __m256i a0 = _mm256_setr_epi64x(at(0), at(1), at(2), at(3));
    const __m256i b0 = _mm256_setr_epi64x(at(4), at(5), at(6), at(7));
    const __m256i a1 = _mm256_setr_epi64x(below(0), below(1), below(2), below(3));
    const __m256i b1 = _mm256_setr_epi64x(below(4), below(5), below(6), below(7));
    const __m256i c00 = EvenLanes(a0, b0), c01 = OddLanes(a0, b0);
    const __m256i c10 = EvenLanes(a1, b1), c11 = OddLanes(a1, b1);
    wu = _mm256_permutevar8x32_epi32(wu, order);
    wv = _mm256_permutevar8x32_epi32(wv, order);
    const __m256i w11 = _mm256_srli_epi32(_mm256_mullo_epi32(wu, wv), 8);
    const __m256i w01 = _mm256_sub_epi32(wu, w11), w10 = _mm256_sub_epi32(wv, w11);
    const __m256i w00 = _mm256_add_epi32(_mm256_sub_epi32(_mm256_sub_epi32(k256i, wu), wv), w11);
    __m256i rgbx = _mm256_or_si256(Blend4(c00, c01, c10, c11, w00, w01, w10, w11, rb_mask),
                                   Blend4(c00, c01, c10, c11, w00, w01, w10, w11, g_mask));
    rgbx = _mm256_permutevar8x32_epi32(rgbx, order);
    rgbx = _mm256_blendv_epi8(walls, rgbx, _mm256_castps_si256(hit));
    const __m128i lo = _mm_shuffle_epi8(_mm256_castsi256_si128(rgbx), pack);
    const __m128i hi = _mm_shuffle_epi8(_mm256_extracti128_si256(rgbx, 1), pack);
    std::memcpy(out + 3 * u, &lo, 12);
    std::memcpy(out + 3 * u + 12, &hi, 12);
  }
  for (; u < width; ++u) {
    const std::uint32_t c = GroundPixel(f, xs[u], ys != nullptr ? ys[u] : y);
    out[3 * u] = static_cast<std::uint8_t>(c);
    out[3 * u + 1] = static_cast<std::uint8_t>(c >> 8);
    out[3 * u + 2] = static_cast<std::uint8_t>(c >> 16);
  }
}

}  // namespace autodrive::vehicle_sim::internal
