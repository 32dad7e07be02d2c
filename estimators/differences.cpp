#include "estimators/differences.hpp"

#include <algorithm>

namespace stiffid::estimators {

Eigen::MatrixXd central_differences(const Eigen::Ref<const Eigen::MatrixXd>& x, double dt_s) {
  const Eigen::Index s = x.rows();
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(s, x.cols());
  for (Eigen::Index i = 0; i < s; ++i) {
    const Eigen::Index a = std::max<Eigen::Index>(i - 1, 0), b = std::min(i + 1, s - 1);
    if (b > a) d.row(i) = (x.row(b) - x.row(a)) / (static_cast<double>(b - a) * dt_s);
  }
  return d;
}

}  // namespace stiffid::estimators
