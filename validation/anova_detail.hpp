#pragma once
// Internals shared by the ANOVA files: contrast bases, tensor projections, distributions, term
// enumeration. Not part of the public API.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace stiffid::validation::detail {

/// Orthonormal contrasts of a factor with L levels: (L x (L-1)) normalized Helmert columns, each
/// orthogonal to the ones vector and to each other.
Eigen::MatrixXd orthonormal_contrasts(int levels);

/// Projects the rows of y (R x C, C = prod dims, cells in row-major order: first factor slowest)
/// on the Kronecker product of, per factor f, its orthonormal contrasts when f is in `term` and
/// ones / sqrt(L_f) otherwise. Returns (R x prod_{f in term} (L_f - 1)). Applied mode by mode, so
/// the Kronecker matrix (C x d) is never formed.
Eigen::MatrixXd project_term(const Eigen::MatrixXd& y, const std::vector<int>& dims,
                             const std::vector<int>& term);

/// Non-empty subsets of {0..k-1} in R's term order: by size, then lexicographic (a, b, c, a:b,
/// a:c, b:c, a:b:c).
std::vector<std::vector<int>> terms_by_order(int k);

/// P(F(df1, df2) > f) from the complement of the CDF (exact for tiny p); 1 for f <= 0.
double f_upper_p(double f, double df1, double df2);
/// Two-sided P(|T(df)| > |t|).
double t_two_sided_p(double t, double df);
/// P(chi2(df) > x).
double chi2_upper_p(double x, double df);

/// Holm step-down adjusted p-values (R's p.adjust(method = "holm")).
std::vector<double> holm(const std::vector<double>& p);

/// Names joined by ':'.
std::string join_names(const std::vector<std::string>& names);

}  // namespace stiffid::validation::detail
