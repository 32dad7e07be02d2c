#include "validation/anova_detail.hpp"

#include <algorithm>
#include <boost/math/distributions/chi_squared.hpp>
#include <boost/math/distributions/fisher_f.hpp>
#include <boost/math/distributions/students_t.hpp>
#include <cassert>
#include <cmath>
#include <numeric>

#include "validation/anova.hpp"

namespace stiffid::validation {

const char* to_string(EffectType type) {
  switch (type) {
    case EffectType::within:
      return "within";
    case EffectType::between:
      return "between";
    case EffectType::fixed:
      return "fixed";
    case EffectType::random:
      return "random";
  }
  return "?";
}

namespace detail {

Eigen::MatrixXd orthonormal_contrasts(int levels) {
  assert(levels >= 1);
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(levels, levels - 1);
  for (int j = 0; j < levels - 1; ++j) {
    const double norm = std::sqrt(static_cast<double>((j + 1) * (j + 2)));
    c.col(j).head(j + 1).setConstant(1.0 / norm);
    c(j + 1, j) = -(j + 1) / norm;
  }
  return c;
}

Eigen::MatrixXd project_term(const Eigen::MatrixXd& y, const std::vector<int>& dims,
                             const std::vector<int>& term) {
  Eigen::MatrixXd current = y;
  std::vector<int> shape = dims;
  for (size_t m = 0; m < dims.size(); ++m) {
    const int levels = dims[m];
    const bool in_term = std::find(term.begin(), term.end(), static_cast<int>(m)) != term.end();
    const Eigen::MatrixXd basis =
        in_term ? orthonormal_contrasts(levels)
                : Eigen::MatrixXd::Constant(levels, 1, 1.0 / std::sqrt(levels));
    const int q = static_cast<int>(basis.cols());
    long outer = 1, inner = 1;
    for (size_t i = 0; i < m; ++i) outer *= shape[i];
    for (size_t i = m + 1; i < shape.size(); ++i) inner *= shape[i];
    Eigen::MatrixXd next = Eigen::MatrixXd::Zero(current.rows(), outer * q * inner);
    for (long o = 0; o < outer; ++o) {
      for (int l = 0; l < levels; ++l) {
        for (int j = 0; j < q; ++j) {
          const double a = basis(l, j);
          if (a == 0.0) continue;
          next.middleCols((o * q + j) * inner, inner) +=
              a * current.middleCols((o * levels + l) * inner, inner);
        }
      }
    }
    current = std::move(next);
    shape[m] = q;
  }
  return current;
}

std::vector<std::vector<int>> terms_by_order(int k) {
  std::vector<std::vector<int>> out;
  for (int size = 1; size <= k; ++size) {
    std::vector<bool> pick(k, false);
    std::fill(pick.begin(), pick.begin() + size, true);
    do {
      std::vector<int> term;
      for (int i = 0; i < k; ++i) {
        if (pick[i]) term.push_back(i);
      }
      out.push_back(term);
    } while (std::prev_permutation(pick.begin(), pick.end()));
  }
  return out;
}

double f_upper_p(double f, double df1, double df2) {
  if (!(f > 0.0)) return 1.0;
  if (std::isinf(f)) return 0.0;
  const boost::math::fisher_f_distribution<double> dist(df1, df2);
  return boost::math::cdf(boost::math::complement(dist, f));
}

double t_two_sided_p(double t, double df) {
  if (std::isinf(t)) return 0.0;
  const boost::math::students_t_distribution<double> dist(df);
  return std::min(1.0, 2.0 * boost::math::cdf(boost::math::complement(dist, std::fabs(t))));
}

double chi2_upper_p(double x, double df) {
  if (!(x > 0.0)) return 1.0;
  const boost::math::chi_squared_distribution<double> dist(df);
  return boost::math::cdf(boost::math::complement(dist, x));
}

std::vector<double> holm(const std::vector<double>& p) {
  const size_t m = p.size();
  std::vector<size_t> order(m);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return p[a] < p[b]; });
  std::vector<double> out(m);
  double running = 0.0;
  for (size_t i = 0; i < m; ++i) {
    running = std::max(running, std::min(1.0, static_cast<double>(m - i) * p[order[i]]));
    out[order[i]] = running;
  }
  return out;
}

std::string join_names(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ":" : "") + names[i];
  return out;
}

}  // namespace detail
}  // namespace stiffid::validation
