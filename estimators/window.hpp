#pragma once
// Tapering windows for spectral estimation, sample for sample as scipy.signal.get_window: the
// periodic ("DFT-even", scipy's fftbins=True, the default for Welch spectra) and the symmetric
// (scipy's sym=True, for filter design) variants of the Hann, Hamming, Kaiser and rectangular
// windows. Used by Welch spectra (spectra.hpp), correlation tapers and time-frequency analysis.

#include <Eigen/Core>
#include <string>

namespace stiffid::estimators {

/// Which variant of a window: periodic = the first n samples of the symmetric window of length
/// n + 1 (scipy get_window default, fftbins=True); symmetric = w[k] == w[n - 1 - k].
enum class WindowSymmetry { periodic, symmetric };

/// A window shape (value type). Text form: "hann", "hamming", "kaiser:BETA" (BETA >= 0,
/// dimensionless shape parameter), "rect" (aliases "rectangular", "boxcar").
class Window {
 public:
  enum class Kind { rectangular, hann, hamming, kaiser };

  static Window rectangular() { return Window(Kind::rectangular, 0.0); }
  /// Hann: w = 0.5 - 0.5 cos(2 pi k / L), L = n (periodic) or n - 1 (symmetric).
  static Window hann() { return Window(Kind::hann, 0.0); }
  /// Hamming: w = 0.54 - 0.46 cos(2 pi k / L).
  static Window hamming() { return Window(Kind::hamming, 0.0); }
  /// Kaiser: w = I0(beta sqrt(1 - ((k - a) / a)^2)) / I0(beta), a = L / 2. Throws InputError
  /// unless 0 <= beta <= kMaxKaiserBeta (I0 overflows a double beyond it).
  static Window kaiser(double beta);
  /// Parses the text form (case-insensitive); throws InputError naming `flag` (e.g. "--window")
  /// and the accepted forms on anything else.
  static Window parse(const std::string& text, const std::string& flag = "window");

  static constexpr double kMaxKaiserBeta = 700.0;

  Kind kind() const { return kind_; }
  double beta() const { return beta_; }  ///< Kaiser shape parameter (0 for other kinds)
  /// Canonical text form ("hann", "kaiser:8", ...), accepted by parse.
  std::string name() const;

  /// Window samples for length n >= 0 (n samples, dimensionless). n <= 1 gives ones, as scipy.
  Eigen::VectorXd samples(int n, WindowSymmetry symmetry = WindowSymmetry::periodic) const;
  Eigen::VectorXd periodic(int n) const { return samples(n, WindowSymmetry::periodic); }
  Eigen::VectorXd symmetric(int n) const { return samples(n, WindowSymmetry::symmetric); }

  bool operator==(const Window& other) const = default;

 private:
  Window(Kind kind, double beta) : kind_(kind), beta_(beta) {}
  Kind kind_;
  double beta_;
};

}  // namespace stiffid::estimators
