#include "estimators/tfa_window.hpp"

#include <boost/math/special_functions/bessel.hpp>
#include <cassert>
#include <cmath>
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
    throw InputError("Gaussian window: sigma (fraction of the window length) must be in (0, 10], "
                     "got " + std::to_string(sigma_fraction));
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
    case Kind::kaiser: return "kaiser:" + std::to_string(parameter_);
    case Kind::hann: return "hann";
    case Kind::gaussian: return "gaussian:" + std::to_string(parameter_);
  }
  return "";
}

double TfWindow::value(double x) const {
  switch (kind_) {
    case Kind::kaiser: {
      const double r = std::sqrt(std::max(0.0, 1.0 - x * x));
      return boost::math::cyl_bessel_i(0, parameter_ * r) / boost::math::cyl_bessel_i(0, parameter_);
    }
    case Kind::hann: return 0.5 + 0.5 * std::cos(M_PI * x);
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
      // d/dx I0(beta r) = beta I1(beta r) dr/dx, dr/dx = -x / r; I1(beta r) / r -> beta / 2 at r = 0.
      const double beta = parameter_;
      const double r = std::sqrt(std::max(0.0, 1.0 - x * x));
      const double i1_over_r =
          r < 1e-8 ? beta / 2.0 : boost::math::cyl_bessel_i(1, beta * r) / r;
      return -beta * x * i1_over_r / boost::math::cyl_bessel_i(0, beta);
    }
    case Kind::hann: return -0.5 * M_PI * std::sin(M_PI * x);
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
  for (int i = 0; i < len; ++i) c.th(i) = (lo + i) * step_s_ * c.h(i);
  return c;
}

SampledWindow::Transform SampledWindow::transform(const Cut& cut, double step_s,
                                                  std::complex<double> s) {
  // exp(s (lo + i) dt) as four interleaved geometric sequences stepping by r^4 (independent
  // multiply chains, real arithmetic: this sum is the spectrogram method's inner loop), then the
  // remaining 0-3 terms.
  using cd = std::complex<double>;
  const cd ratio = std::exp(s * step_s);
  const cd ratio4 = (ratio * ratio) * (ratio * ratio);
  constexpr int kLanes = 4;
  double er[kLanes], ei[kLanes];
  cd e = std::exp(s * (cut.lo * step_s));
  for (int q = 0; q < kLanes; ++q, e *= ratio) {
    er[q] = e.real();
    ei[q] = e.imag();
  }
  double w_re[kLanes] = {}, w_im[kLanes] = {}, wd_re[kLanes] = {}, wd_im[kLanes] = {};
  double wt_re[kLanes] = {}, wt_im[kLanes] = {}, wdt_re[kLanes] = {}, wdt_im[kLanes] = {};
  const int len = static_cast<int>(cut.h.size());
  const double r4r = ratio4.real(), r4i = ratio4.imag();
  int i = 0;
  for (; i + kLanes <= len; i += kLanes) {
    for (int q = 0; q < kLanes; ++q) {
      const double h = cut.h(i + q), dh = cut.dh(i + q);
      const double u = (cut.lo + i + q) * step_s;
      const double uh = u * h, udh = u * dh;
      w_re[q] += h * er[q];
      w_im[q] += h * ei[q];
      wd_re[q] += dh * er[q];
      wd_im[q] += dh * ei[q];
      wt_re[q] += uh * er[q];
      wt_im[q] += uh * ei[q];
      wdt_re[q] += udh * er[q];
      wdt_im[q] += udh * ei[q];
      const double nr = er[q] * r4r - ei[q] * r4i;
      ei[q] = er[q] * r4i + ei[q] * r4r;
      er[q] = nr;
    }
  }
  Transform t{};
  for (int q = 0; q < kLanes; ++q) {
    t.w += cd(w_re[q], w_im[q]);
    t.wd += cd(wd_re[q], wd_im[q]);
    t.wt += cd(wt_re[q], wt_im[q]);
    t.wdt += cd(wdt_re[q], wdt_im[q]);
  }
  e = cd(er[0], ei[0]);  // exp(s (lo + i) dt)
  for (; i < len; ++i, e *= ratio) {
    const double u = (cut.lo + i) * step_s;
    t.w += cut.h(i) * e;
    t.wd += cut.dh(i) * e;
    t.wt += u * cut.h(i) * e;
    t.wdt += u * cut.dh(i) * e;
  }
  return t;
}

}  // namespace stiffid::estimators
