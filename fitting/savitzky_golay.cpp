#include "fitting/savitzky_golay.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <string>

#include "data/error.hpp"

namespace stiffid::fitting {

SavitzkyGolayResult savitzky_golay(const Eigen::MatrixXd& x, int window, int order, double dt_s) {
  const int s = static_cast<int>(x.rows());
  if (window % 2 == 0 || window < 3 || order < 2 || order >= window || window > s) {
    throw InputError("Savitzky-Golay: expected an odd window of 3.." + std::to_string(s) +
                     " samples and 2 <= order < window, got window " + std::to_string(window) +
                     ", order " + std::to_string(order));
  }
  const int half = window / 2;
  // Vandermonde on offsets u = j - half (samples); coefficients a = pinv(V) y.
  Eigen::MatrixXd v(window, order + 1);
  for (int j = 0; j < window; ++j) {
    for (int k = 0; k <= order; ++k) v(j, k) = std::pow(static_cast<double>(j - half), k);
  }
  const Eigen::MatrixXd pinv = v.colPivHouseholderQr().solve(Eigen::MatrixXd::Identity(window, window));
  // Rows of weights giving value, first and second derivative at window position c.
  auto weights = [&](int c, int deriv) {
    Eigen::RowVectorXd e = Eigen::RowVectorXd::Zero(order + 1);
    const double u = c - half;
    for (int k = deriv; k <= order; ++k) {
      const double factor = deriv == 0 ? 1.0 : deriv == 1 ? k : static_cast<double>(k * (k - 1));
      e(k) = factor * std::pow(u, k - deriv);
    }
    return Eigen::RowVectorXd(e * pinv);
  };
  SavitzkyGolayResult r{Eigen::MatrixXd(s, x.cols()), Eigen::MatrixXd(s, x.cols()),
                        Eigen::MatrixXd(s, x.cols())};
  for (int i = 0; i < s; ++i) {
    const int start = std::clamp(i - half, 0, s - window);
    const int c = i - start;
    const auto block = x.middleRows(start, window);
    r.value.row(i) = weights(c, 0) * block;
    r.first.row(i) = weights(c, 1) * block / dt_s;
    r.second.row(i) = weights(c, 2) * block / (dt_s * dt_s);
  }
  return r;
}

}  // namespace stiffid::fitting
