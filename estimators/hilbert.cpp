#include "estimators/hilbert.hpp"

#include <complex>

#include "estimators/fft.hpp"

namespace stiffid::estimators {

Eigen::MatrixXd hilbert_transform(const Eigen::Ref<const Eigen::MatrixXd>& x) {
  const int samples = static_cast<int>(x.rows());
  const int columns = static_cast<int>(x.cols());
  if (samples < 2 || columns < 1) return Eigen::MatrixXd::Zero(samples, columns);
  int n = 2;
  while (n < 2 * samples) n *= 2;
  RealFft fft(n, columns);
  Eigen::MatrixXd padded = Eigen::MatrixXd::Zero(n, columns);
  padded.topRows(samples) = x;
  Eigen::MatrixXcd spectrum = fft.forward(padded);
  spectrum.row(0).setZero();
  spectrum.row(n / 2).setZero();
  spectrum.middleRows(1, n / 2 - 1) *= std::complex<double>(0.0, -1.0);
  return fft.inverse(spectrum).topRows(samples);
}

}  // namespace stiffid::estimators
