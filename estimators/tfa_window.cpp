#include "estimators/tfa_window.hpp"

#include <boost/math/special_functions/bessel.hpp>
#include <cassert>
#include <cmath>
#include <cstring>
#include <string>

#include "data/error.hpp"

namespace stiffid::estimators {

TfWindow TfWindow::kaiser(double beta) {
  if (!(beta >= 0.0 && beta <= 700.0)) {
    throw InputError("Kaiser window: beta must be in [0, 700], got " + std::to_string(beta));
  }
  return TfWindow(Kind::kaiser, beta);
}

TfWindow TfWindow::gaussian(double sigma_fraction) {
  if (!(sigma_fraction > 0.0 && sigma_fraction <= 10.0)) {
    throw InputError(
        "Gaussian window: sigma (fraction of the window length) must be in (0, 10], "
        "got " +
        std::to_string(sigma_fraction));
  }
  return TfWindow(Kind::gaussian, sigma_fraction);
}

TfWindow TfWindow::parse(const std::string& text, const std::string& flag) {
  const auto colon = text.find(':');
  const std::string kind = text.substr(0, colon);
  const bool has_value = colon != std::string::npos;
  double value = 0.0;
  if (has_value) {
    const std::string number = text.substr(colon + 1);
    size_t used = 0;
    try {
      value = std::stod(number, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (number.empty() || used != number.size() || !std::isfinite(value)) {
      throw InputError(flag + ": expected a number after ':' in '" + text + "'");
    }
  }
  if (kind == "kaiser") return kaiser(has_value ? value : 3.0);
  if (kind == "hann" && !has_value) return hann();
  if (kind == "gaussian") return has_value ? gaussian(value) : gaussian();
  throw InputError(flag + ": unknown window '" + text +
                   "'; expected kaiser:BETA, hann or gaussian:SIGMA_FRACTION");
}

std::string TfWindow::name() const {
  switch (kind_) {
    case Kind::kaiser:
      return "kaiser:" + std::to_string(parameter_);
    case Kind::hann:
      return "hann";
    case Kind::gaussian:
      return "gaussian:" + std::to_string(parameter_);
  }
  return "";
}

double TfWindow::value(double x) const {
  switch (kind_) {
    case Kind::kaiser: {
      const double r = std::sqrt(std::max(0.0, 1.0 - x * x));
      return boost::math::cyl_bessel_i(0, parameter_ * r) /
             boost::math::cyl_bessel_i(0, parameter_);
    }
    case Kind::hann:
      return 0.5 + 0.5 * std::cos(M_PI * x);
    case Kind::gaussian: {
      const double z = x / (2.0 * parameter_);  // u / (sigma T) with u = x T / 2
      return std::exp(-0.5 * z * z);
    }
  }
  return 0.0;
}

double TfWindow::slope(double x) const {
  switch (kind_) {
    case Kind::kaiser: {
      // d/dx I0(beta r) = beta I1(beta r) dr/dx, dr/dx = -x / r; I1(beta r) / r -> beta / 2 at r =
      // 0.
      const double beta = parameter_;
      const double r = std::sqrt(std::max(0.0, 1.0 - x * x));
      const double i1_over_r = r < 1e-8 ? beta / 2.0 : boost::math::cyl_bessel_i(1, beta * r) / r;
      return -beta * x * i1_over_r / boost::math::cyl_bessel_i(0, beta);
    }
    case Kind::hann:
      return -0.5 * M_PI * std::sin(M_PI * x);
    case Kind::gaussian: {
      const double s2 = 4.0 * parameter_ * parameter_;
      return -x / s2 * std::exp(-0.5 * x * x / s2);
    }
  }
  return 0.0;
}

SampledWindow::SampledWindow(const TfWindow& shape, int half_length, double step_s)
    : shape_(shape), half_(half_length), step_s_(step_s) {
  assert(half_length >= 1 && step_s > 0.0);
  value_.resize(2 * half_ + 1);
  slope_per_s_.resize(2 * half_ + 1);
  const double dx_du = 1.0 / (half_ * step_s_);  // x = 2u/T = u / (L dt)
  for (int n = -half_; n <= half_; ++n) {
    const double x = static_cast<double>(n) / half_;
    value_(n + half_) = shape_.value(x);
    slope_per_s_(n + half_) = shape_.slope(x) * dx_du;
  }
}

SampledWindow::Cut SampledWindow::cut(int lo, int hi) const {
  assert(-half_ <= lo && lo <= hi && hi <= half_);
  Cut c;
  c.lo = lo;
  c.hi = hi;
  const int len = hi - lo + 1;
  c.h = value_.segment(lo + half_, len);
  c.dh = slope_per_s_.segment(lo + half_, len);
  if (len > 1) {  // trapezoid end weights
    c.h(0) *= 0.5;
    c.h(len - 1) *= 0.5;
    c.dh(0) *= 0.5;
    c.dh(len - 1) *= 0.5;
  }
  // The window times the indicator of [lo dt, hi dt] has the distributional derivative
  // h' + h(lo dt) delta(u - lo dt) - h(hi dt) delta(u - hi dt): the edge steps, weight 1/dt each.
  c.dh(0) += value_(lo + half_) / step_s_;
  c.dh(len - 1) -= value_(hi + half_) / step_s_;
  c.th.resize(len);
  c.tdh.resize(len);
  for (int i = 0; i < len; ++i) {
    c.th(i) = (lo + i) * step_s_ * c.h(i);
    c.tdh(i) = (lo + i) * step_s_ * c.dh(i);
  }
  return c;
}

namespace {
/// Four doubles as one value (GCC/Clang vector extension; two SSE2 registers, one AVX register):
/// keeps the sums of SampledWindow::transform in registers.
typedef double Lanes __attribute__((vector_size(4 * sizeof(double))));

/// exp(s (lo + q) dt), q = 0..3, as four lanes (re, im), the ratio exp(s dt) of consecutive
/// terms and the step exp(4 s dt) of each lane: four interleaved geometric sequences.
struct GeometricLanes {
  Lanes re, im;
  std::complex<double> ratio, ratio4;
};

inline GeometricLanes geometric_lanes(std::complex<double> s, double step_s, int lo) {
  GeometricLanes g;
  g.ratio = std::exp(s * step_s);
  g.ratio4 = (g.ratio * g.ratio) * (g.ratio * g.ratio);
  std::complex<double> e = std::exp(s * (lo * step_s));
  for (int q = 0; q < 4; ++q, e *= g.ratio) {
    g.re[q] = e.real();
    g.im[q] = e.imag();
  }
  return g;
}
}  // namespace

// Built for AVX2 too (chosen at load time on machines that have it): the four-lane sums are one
// instruction each instead of two. No FMA (not in the "avx2" target), so both builds round alike
// and the results are the same bits on any machine.
__attribute__((target_clones("avx2", "default"))) SampledWindow::Transform SampledWindow::transform(
    const Cut& cut, double step_s, std::complex<double> s) {
  // exp(s (lo + i) dt) as four interleaved geometric sequences stepping by r^4 (independent
  // multiply chains, real arithmetic in four lanes: this sum is the spectrogram method's inner
  // loop), then the remaining 0-3 terms. Lane q sums the terms i = q mod 4.
  using cd = std::complex<double>;
  const GeometricLanes lanes = geometric_lanes(s, step_s, cut.lo);
  const cd ratio = lanes.ratio, ratio4 = lanes.ratio4;
  Lanes er = lanes.re, ei = lanes.im;
  cd e;
  // Real and imaginary parts of the sums with the windows h, dh, t h and t dh.
  Lanes h_re = {}, h_im = {}, dh_re = {}, dh_im = {}, th_re = {}, th_im = {}, tdh_re = {},
        tdh_im = {};
  const double* h = cut.h.data();
  const double* dh = cut.dh.data();
  const double* th = cut.th.data();
  const double* tdh = cut.tdh.data();
  const int len = static_cast<int>(cut.h.size());
  const double r4r = ratio4.real(), r4i = ratio4.imag();
  int i = 0;
  for (; i + 4 <= len; i += 4) {
    Lanes vh, vdh, vth, vtdh;
    std::memcpy(&vh, h + i, sizeof(Lanes));
    std::memcpy(&vdh, dh + i, sizeof(Lanes));
    std::memcpy(&vth, th + i, sizeof(Lanes));
    std::memcpy(&vtdh, tdh + i, sizeof(Lanes));
    h_re += vh * er;
    h_im += vh * ei;
    dh_re += vdh * er;
    dh_im += vdh * ei;
    th_re += vth * er;
    th_im += vth * ei;
    tdh_re += vtdh * er;
    tdh_im += vtdh * ei;
    const Lanes next_re = er * r4r - ei * r4i;
    ei = er * r4i + ei * r4r;
    er = next_re;
  }
  Transform t{};
  for (int q = 0; q < 4; ++q) {
    t.w += cd(h_re[q], h_im[q]);
    t.wd += cd(dh_re[q], dh_im[q]);
    t.wt += cd(th_re[q], th_im[q]);
    t.wdt += cd(tdh_re[q], tdh_im[q]);
  }
  e = cd(er[0], ei[0]);  // exp(s (lo + i) dt)
  for (; i < len; ++i, e *= ratio) {
    t.w += h[i] * e;
    t.wd += dh[i] * e;
    t.wt += th[i] * e;
    t.wdt += tdh[i] * e;
  }
  return t;
}

SampledWindow::ChirpedCut SampledWindow::chirped(const Cut& cut, double step_s,
                                                 std::complex<double> g, bool moments) {
  using cd = std::complex<double>;
  ChirpedCut c;
  c.lo = cut.lo;
  c.windows = moments ? 6 : 4;
  const int len = static_cast<int>(cut.h.size());
  c.re.resize(len, c.windows);
  c.im.resize(len, c.windows);
  // exp(g u^2 / 2) along u = (lo + i) dt: the ratio of consecutive terms,
  // exp(g (2 (lo + i) + 1) dt^2 / 2), itself steps by exp(g dt^2).
  const double u0 = cut.lo * step_s;
  cd e = std::exp(0.5 * g * u0 * u0);
  cd ratio = std::exp(0.5 * g * (2.0 * cut.lo + 1.0) * step_s * step_s);
  const cd ratio_step = std::exp(g * step_s * step_s);
  for (int i = 0; i < len; ++i) {
    const double u = (cut.lo + i) * step_s;
    const double w[6] = {cut.h(i), cut.dh(i), cut.th(i), cut.tdh(i), u * cut.th(i), u * cut.tdh(i)};
    for (int k = 0; k < c.windows; ++k) {
      c.re(i, k) = w[k] * e.real();
      c.im(i, k) = w[k] * e.imag();
    }
    e *= ratio;
    ratio *= ratio_step;
  }
  return c;
}

namespace {
// The sums of SampledWindow::transform(ChirpedCut) for WINDOWS complex windows (their
// conjugates when SIGN is -1), in four lanes.
template <int kWindows, int kSign>
__attribute__((target_clones("avx2", "default"))) void chirped_sums(
    const SampledWindow::ChirpedCut& cut, double step_s, std::complex<double> s,
    std::complex<double>* out) {
  using cd = std::complex<double>;
  const GeometricLanes lanes = geometric_lanes(s, step_s, cut.lo);
  const cd ratio = lanes.ratio, ratio4 = lanes.ratio4;
  Lanes er = lanes.re, ei = lanes.im;
  cd e;
  Lanes acc_re[kWindows] = {}, acc_im[kWindows] = {};
  const int len = static_cast<int>(cut.re.rows());
  const double r4r = ratio4.real(), r4i = ratio4.imag();
  int i = 0;
  for (; i + 4 <= len; i += 4) {
    for (int k = 0; k < kWindows; ++k) {
      Lanes ar, ai;
      std::memcpy(&ar, cut.re.col(k).data() + i, sizeof(Lanes));
      std::memcpy(&ai, cut.im.col(k).data() + i, sizeof(Lanes));
      if (kSign < 0) ai = -ai;
      acc_re[k] += ar * er - ai * ei;
      acc_im[k] += ar * ei + ai * er;
    }
    const Lanes next_re = er * r4r - ei * r4i;
    ei = er * r4i + ei * r4r;
    er = next_re;
  }
  for (int k = 0; k < kWindows; ++k) {
    out[k] = 0.0;
    for (int q = 0; q < 4; ++q) out[k] += cd(acc_re[k][q], acc_im[k][q]);
  }
  e = cd(er[0], ei[0]);
  for (; i < len; ++i, e *= ratio) {
    for (int k = 0; k < kWindows; ++k) out[k] += cd(cut.re(i, k), kSign * cut.im(i, k)) * e;
  }
}
}  // namespace

SampledWindow::Transform SampledWindow::transform(const ChirpedCut& cut, double step_s,
                                                  std::complex<double> s, bool conjugate) {
  std::complex<double> sums[6] = {};
  if (cut.windows == 6) {
    conjugate ? chirped_sums<6, -1>(cut, step_s, s, sums)
              : chirped_sums<6, 1>(cut, step_s, s, sums);
  } else {
    conjugate ? chirped_sums<4, -1>(cut, step_s, s, sums)
              : chirped_sums<4, 1>(cut, step_s, s, sums);
  }
  return Transform{sums[0], sums[1], sums[2], sums[3], sums[4], sums[5]};
}

}  // namespace stiffid::estimators
