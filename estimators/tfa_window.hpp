#pragma once
// Analysis windows for the reassigned spectrogram (Auger & Flandrin 1995): a continuous window
// shape h(u) on u in [-T/2, T/2] with its analytic derivative, sampled into the three discrete
// windows the reassignment needs (h, the time-weighted u h and the derivative h' including the
// steps at the window edges), and the exact "window transform" W(s) = sum_n h[n] exp(s n dt) used
// to turn STFT values of damped exponentials into amplitudes (ridge.hpp).
//
// Values of Kaiser and Hann agree with estimators/window.hpp's symmetric windows of odd length
// 2L + 1; this file adds what that one does not have: the derivative, the Gaussian, and windows
// cut short at the ends of the analysed region.

#include <Eigen/Core>
#include <complex>
#include <string>

namespace stiffid::estimators {

/// A continuous window shape h(u), u in [-T/2, T/2], normalised so h(0) = 1 (dimensionless).
class TfWindow {
 public:
  enum class Kind { kaiser, hann, gaussian };

  /// Kaiser: h = I0(beta sqrt(1 - (2u/T)^2)) / I0(beta); does not vanish at u = +-T/2.
  static TfWindow kaiser(double beta);
  /// Hann: h = 0.5 + 0.5 cos(2 pi u / T); vanishes with its slope at the edges.
  static TfWindow hann() { return TfWindow(Kind::hann, 0.0); }
  /// Gaussian truncated at +-T/2: h = exp(-u^2 / (2 (sigma T)^2)), sigma = standard deviation as
  /// a fraction of the window length T (default 1/6: the edges sit at 3 standard deviations).
  static TfWindow gaussian(double sigma_fraction = 1.0 / 6.0);
  /// Text form "kaiser:BETA", "kaiser" (beta 3), "hann", "gaussian:SIGMA", "gaussian"; throws
  /// InputError naming `flag` and the accepted forms on anything else.
  static TfWindow parse(const std::string& text, const std::string& flag = "--window");

  Kind kind() const { return kind_; }
  double parameter() const { return parameter_; }  ///< Kaiser beta or Gaussian sigma fraction
  std::string name() const;                        ///< canonical text form, accepted by parse

  /// h(u) for x = 2u/T in [-1, 1] (dimensionless).
  double value(double x) const;
  /// dh/dx for x = 2u/T in [-1, 1]; dh/du = (2/T) dh/dx. Finite at the edges for all kinds.
  double slope(double x) const;

 private:
  TfWindow(Kind kind, double parameter) : kind_(kind), parameter_(parameter) {}
  Kind kind_;
  double parameter_;
};

/// Discrete windows of odd length 2L + 1 at sampling step dt (s), offsets n = -L..L from the frame
/// centre, window length T = 2 L dt. Sampled with trapezoid end weights so that discrete sums are
/// second-order accurate approximations of the continuous integrals (Euler-Maclaurin); the
/// derivative window adds the edge steps h(edge)/dt as Dirac terms, so that for x(t) = exp(lambda
/// t) sum_n x[c+n] dh[n] exp(-i nu n dt) = -(lambda - i nu) sum_n x[c+n] h[n] exp(-i nu n dt) up to
/// O(dt^2), whether or not h vanishes at its edges (the Kaiser window does not).
class SampledWindow {
 public:
  SampledWindow(const TfWindow& shape, int half_length, double step_s);

  int half_length() const { return half_; }  ///< L, samples
  double step_s() const { return step_s_; }  ///< dt, s

  /// Coefficients over the offsets [lo, hi] (-L <= lo <= hi <= L) of the window cut to those
  /// offsets (the region the signal is valid in): trapezoid halves at lo and hi, and edge steps at
  /// lo and hi in the derivative window. Vectors of length hi - lo + 1, index 0 = offset lo.
  struct Cut {
    int lo = 0, hi = 0;
    Eigen::VectorXd h;    ///< window, dimensionless
    Eigen::VectorXd th;   ///< time-weighted window n dt h[n], s
    Eigen::VectorXd dh;   ///< derivative window dh/du with edge steps, 1/s
    Eigen::VectorXd tdh;  ///< time-weighted derivative window n dt dh[n], dimensionless
  };
  Cut cut(int lo, int hi) const;

  /// Window transforms of a cut at complex rate s (1/s): W(s) = sum_n h[n] exp(s n dt) and
  /// Wd(s) = sum_n dh[n] exp(s n dt). For x(t) = c exp(lambda (t - t_c)) an STFT bin at angular
  /// frequency nu (rad/s) equals c W(lambda - i nu) (and c Wd(lambda - i nu) for dh), exactly.
  struct Transform {
    std::complex<double> w, wd, wt, wdt;  ///< W, Wd and their s-derivatives sum n dt h exp(...)
    /// sum (n dt)^2 h[n] exp(...) and the same with dh: twice the derivatives of W and Wd with
    /// respect to the chirp rate g (from a ChirpedCut made with moments; zero otherwise).
    std::complex<double> wtt, wdtt;
  };
  static Transform transform(const Cut& cut, double step_s, std::complex<double> s);

  /// A cut's windows multiplied by exp(g u^2 / 2), u = n dt, for a linear chirp of the rate
  /// (g in 1/s^2, complex: the rate of change of the decay rate, real part, and of the angular
  /// frequency, imaginary part): complex windows h, dh, t h, t dh and, with `moments`, t^2 h and
  /// t^2 dh, as real and imaginary parts.
  struct ChirpedCut {
    int lo = 0;              ///< first window offset (Cut::lo)
    int windows = 4;         ///< 4, or 6 with the second moments
    Eigen::MatrixXd re, im;  ///< (length x windows): h, dh, t h, t dh[, t^2 h, t^2 dh]
  };
  static ChirpedCut chirped(const Cut& cut, double step_s, std::complex<double> g, bool moments);
  /// Window transforms of a linear chirp: W(s, g) = sum_n h[n] exp(s u + g u^2 / 2), likewise Wd,
  /// their s-derivatives (sums with u) and, with moments, their g-derivatives (wtt / 2,
  /// wdtt / 2). For x(t) = c exp(lambda (t - t_c) + g (t - t_c)^2 / 2) an STFT bin at angular
  /// frequency nu equals c W(lambda - i nu, g), exactly. With g = 0 it equals transform() up to
  /// round-off. With `conjugate`, the windows of conj(g) (the complex conjugates of the cut's).
  static Transform transform(const ChirpedCut& cut, double step_s, std::complex<double> s,
                             bool conjugate = false);

 private:
  TfWindow shape_;
  int half_;
  double step_s_;
  Eigen::VectorXd value_, slope_per_s_;  ///< h(n dt) and h'(n dt) (1/s) for n = -L..L
};

}  // namespace stiffid::estimators
