#include "models/butterworth.hpp"

#include <cmath>
#include <complex>
#include <sstream>
#include <vector>

#include "data/error.hpp"

namespace stiffid::models {

Eigen::MatrixXd butterworth_lowpass_sos(int order, double cutoff_hz, double sample_rate_hz) {
  if (order < 1) throw InputError("Butterworth filter: expected an order >= 1");
  if (!(cutoff_hz > 0.0 && cutoff_hz < 0.5 * sample_rate_hz)) {
    std::ostringstream msg;
    msg << "Butterworth filter: cut-off " << cutoff_hz << " Hz must lie in (0, "
        << 0.5 * sample_rate_hz << ") Hz, below the Nyquist frequency";
    throw InputError(msg.str());
  }
  using Complex = std::complex<double>;
  const double fs2 = 2.0 * sample_rate_hz;
  // Pre-warped analog cut-off, rad/s, so the digital filter is -3 dB at cutoff_hz.
  const double warped = fs2 * std::tan(M_PI * cutoff_hz / sample_rate_hz);
  // Analog prototype poles on the left half unit circle, scaled to the cut-off, then mapped by
  // the bilinear transform z = (fs2 + s) / (fs2 - s); all N zeros go to z = -1.
  std::vector<Complex> poles;
  Complex gain_denominator = 1.0;
  for (int m = -order + 1; m < order; m += 2) {
    const Complex s = -warped * std::exp(Complex(0.0, M_PI * m / (2.0 * order)));
    gain_denominator *= fs2 - s;
    poles.push_back((fs2 + s) / (fs2 - s));
  }
  const double gain = std::pow(warped, order) / gain_denominator.real();
  const int sections = (order + 1) / 2;
  Eigen::MatrixXd sos(sections, 6);
  int row = 0;
  // Conjugate pairs: poles with negative imaginary part pair with their mirror images.
  for (const Complex& p : poles) {
    if (p.imag() < 0.0 && std::abs(p.imag()) > 1e-14) {
      sos.row(row++) << 1.0, 2.0, 1.0, 1.0, -2.0 * p.real(), std::norm(p);
    }
  }
  if (order % 2 == 1) {
    for (const Complex& p : poles) {
      if (std::abs(p.imag()) <= 1e-14) sos.row(row++) << 1.0, 1.0, 0.0, 1.0, -p.real(), 0.0;
    }
  }
  sos.block(0, 0, 1, 3) *= gain;
  return sos;
}

Eigen::VectorXd sos_filter(const Eigen::MatrixXd& sos, const Eigen::VectorXd& x) {
  Eigen::VectorXd y = x;
  for (int k = 0; k < sos.rows(); ++k) {
    const double a0 = sos(k, 3);
    const double b0 = sos(k, 0) / a0, b1 = sos(k, 1) / a0, b2 = sos(k, 2) / a0;
    const double a1 = sos(k, 4) / a0, a2 = sos(k, 5) / a0;
    double z1 = 0.0, z2 = 0.0;  // transposed direct form II state
    for (Eigen::Index i = 0; i < y.size(); ++i) {
      const double in = y(i);
      const double out = b0 * in + z1;
      z1 = b1 * in - a1 * out + z2;
      z2 = b2 * in - a2 * out;
      y(i) = out;
    }
  }
  return y;
}

}  // namespace stiffid::models
