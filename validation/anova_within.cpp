// Univariate repeated-measures ANOVA with between-subject factors (car::Anova type III on the
// multivariate linear model of the subject x cell means, as afex::aov_ez reports it).

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include "validation/anova.hpp"
#include "validation/anova_detail.hpp"

namespace stiffid::validation {
namespace {

// Error sums of squares below this fraction of sum(Y^2) are taken as exactly zero: round-off in
// the projections leaves residuals of about C * 2.2e-16 * |y| per cell, i.e. a fraction
// (C * 2.2e-16)^2 < 1e-25 of sum(Y^2) for C < 1e4 cells, while any measured data have residuals
// far above 1e-10 of their RMS.
constexpr double kZeroErrorFraction = 1e-20;
// Eigenvalues of an error SSP matrix below this fraction of the largest make it singular for
// Mauchly's test (its log-determinant would be dominated by round-off).
constexpr double kSingularEigenFraction = 1e-12;

struct Design {
  std::vector<std::string> subjects;             // [N] labels in order of first appearance
  std::vector<int> subject_first_row;            // [N]
  std::vector<FactorCoding> within, between;     // factor codings over the table rows
  std::vector<int> dims;                         // [W] within level counts
  Eigen::MatrixXd y;                             // (N x C) cell means
  std::vector<std::vector<int>> between_levels;  // [N][B] level index per subject
  int averaged_cells = 0, averaged_rows = 0;
};

void check_options(const LongTable& table, const RepeatedMeasuresOptions& o) {
  if (o.subject.empty()) throw InputError(table.source + ": --subject: a subject column is needed");
  if (o.within.empty()) {
    throw InputError(table.source + ": --within: at least one within-subject factor is needed");
  }
  std::set<std::string> seen{o.subject};
  for (const auto* list : {&o.within, &o.between}) {
    for (const auto& name : *list) {
      if (!seen.insert(name).second) {
        throw InputError(table.source + ": '" + name +
                         "' is given twice among --subject, --within and --between");
      }
    }
  }
}

std::string cell_label(const Design& d, const std::vector<int>& levels) {
  std::string out;
  for (size_t f = 0; f < levels.size(); ++f) {
    out += (f ? ", " : "") + d.within[f].name + "=" + d.within[f].levels[levels[f]];
  }
  return out;
}

// Subject x cell means; throws on a subject whose between levels change or who misses a cell.
Design build_design(const LongTable& table, const RepeatedMeasuresOptions& o) {
  Design d;
  const FactorCoding subject = code_factor(table, o.subject, "--subject", 1);
  for (const auto& w : o.within) d.within.push_back(code_factor(table, w, "--within"));
  for (const auto& b : o.between) d.between.push_back(code_factor(table, b, "--between"));
  d.subjects = subject.levels;
  const int n = subject.level_count();
  int cells = 1;
  for (const auto& w : d.within) {
    d.dims.push_back(w.level_count());
    cells *= w.level_count();
  }
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(n, cells);
  Eigen::MatrixXi count = Eigen::MatrixXi::Zero(n, cells);
  d.subject_first_row.assign(n, -1);
  d.between_levels.assign(n, std::vector<int>(d.between.size(), -1));
  for (int r = 0; r < table.row_count(); ++r) {
    const int s = subject.codes[r];
    if (d.subject_first_row[s] < 0) d.subject_first_row[s] = r;
    for (size_t b = 0; b < d.between.size(); ++b) {
      int& level = d.between_levels[s][b];
      if (level < 0) level = d.between[b].codes[r];
      if (level != d.between[b].codes[r]) {
        throw InputError(table.where(r) + ": subject '" + d.subjects[s] + "' has " +
                         d.between[b].name + "='" + d.between[b].levels[d.between[b].codes[r]] +
                         "' but '" + d.between[b].levels[level] + "' at " +
                         table.where(d.subject_first_row[s]) +
                         "; a --between factor must be constant within a subject");
      }
    }
    int cell = 0;
    for (const auto& w : d.within) cell = cell * w.level_count() + w.codes[r];
    sum(s, cell) += table.values[r];
    ++count(s, cell);
  }
  for (int s = 0; s < n; ++s) {
    for (int c = 0; c < cells; ++c) {
      if (count(s, c) == 0) {
        std::vector<int> levels(d.within.size());
        for (int f = static_cast<int>(d.within.size()) - 1, rest = c; f >= 0; --f) {
          levels[f] = rest % d.dims[f];
          rest /= d.dims[f];
        }
        const long missing = (count.array() == 0).count();
        throw InputError(table.source + ": subject '" + d.subjects[s] + "' (first row at " +
                         table.where(d.subject_first_row[s]) + ") has no observation for cell " +
                         cell_label(d, levels) + "; every subject needs every within cell (" +
                         std::to_string(missing) + " subject x cell entr" +
                         (missing == 1 ? "y" : "ies") + " missing in all)");
      }
      if (count(s, c) > 1) {
        ++d.averaged_cells;
        d.averaged_rows += count(s, c);
      }
    }
  }
  d.y = sum.array() / count.cast<double>().array();
  return d;
}

// Between design with sum-to-zero coding (R's contr.sum), full factorial: column blocks per term.
struct BetweenDesign {
  Eigen::MatrixXd x;                      // (N x P)
  std::vector<std::vector<int>> terms;    // [T] factor indices, term 0 = intercept (empty)
  std::vector<int> first_col, col_count;  // [T]
};

BetweenDesign build_between(const LongTable& table, const Design& d) {
  const int n = static_cast<int>(d.subjects.size());
  const int b = static_cast<int>(d.between.size());
  BetweenDesign bd;
  bd.terms.push_back({});
  for (const auto& t : detail::terms_by_order(b)) bd.terms.push_back(t);
  std::vector<Eigen::MatrixXd> blocks;
  for (const auto& term : bd.terms) {
    Eigen::MatrixXd block = Eigen::MatrixXd::Ones(n, 1);
    for (const int f : term) {
      const int levels = d.between[f].level_count();
      Eigen::MatrixXd next(n, block.cols() * (levels - 1));
      for (int s = 0; s < n; ++s) {
        const int level = d.between_levels[s][f];
        for (int j = 0; j < levels - 1; ++j) {
          const double code = level == levels - 1 ? -1.0 : (level == j ? 1.0 : 0.0);
          for (long k = 0; k < block.cols(); ++k)
            next(s, k * (levels - 1) + j) = block(s, k) * code;
        }
      }
      block = std::move(next);
    }
    bd.first_col.push_back(blocks.empty() ? 0 : bd.first_col.back() + bd.col_count.back());
    bd.col_count.push_back(static_cast<int>(block.cols()));
    blocks.push_back(std::move(block));
  }
  const int p = bd.first_col.back() + bd.col_count.back();
  bd.x.resize(n, p);
  for (size_t t = 0; t < blocks.size(); ++t)
    bd.x.middleCols(bd.first_col[t], bd.col_count[t]) = blocks[t];
  // Every combination of between levels needs a subject, else X is rank deficient.
  if (b > 0) {
    std::map<std::vector<int>, int> groups;
    for (int s = 0; s < n; ++s) ++groups[d.between_levels[s]];
    long combos = 1;
    for (const auto& f : d.between) combos *= f.level_count();
    if (static_cast<long>(groups.size()) < combos) {
      std::vector<int> levels(b, 0);
      for (long c = 0; c < combos; ++c) {
        for (int f = b - 1, rest = static_cast<int>(c); f >= 0; --f) {
          levels[f] = rest % d.between[f].level_count();
          rest /= d.between[f].level_count();
        }
        if (!groups.count(levels)) {
          std::string label;
          for (int f = 0; f < b; ++f) {
            label += (f ? ", " : "") + d.between[f].name + "=" + d.between[f].levels[levels[f]];
          }
          throw InputError(table.source + ": no subject in between-subject group " + label +
                           "; every combination of --between levels needs subjects");
        }
      }
    }
  }
  if (n - p < 1) {
    throw InputError(table.source + ": " + std::to_string(n) + " subjects for " +
                     std::to_string(p) +
                     " between-subject parameters leave no error degrees of freedom; at least " +
                     std::to_string(p + 1) + " subjects are needed");
  }
  return bd;
}

// Mauchly's W and p as car (and R's mauchly.test.SSD) compute them: E (d x d) error SSP in an
// orthonormal basis, `n` its error df, `cells` the number C of within cells. Anderson's
// second-order term w2 has 3 d in the textbook; R and car write 3 C there (C = rows of the
// contrast matrix), which we follow to give afex's numbers (only d >= 3 is affected).
MauchlyTest mauchly(const std::string& name, const Eigen::MatrixXd& e, double n, double cells) {
  const Eigen::VectorXd lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(e).eigenvalues();
  const double p = static_cast<double>(e.rows());
  const double log_w = lambda.array().log().sum() - p * std::log(lambda.mean());
  const double rho = 1.0 - (2.0 * p * p + p + 2.0) / (6.0 * p * n);
  const double w2 = (p + 2.0) * (p - 1.0) * (p - 2.0) *
                    (2.0 * p * p * p + 6.0 * p * p + 3.0 * cells + 2.0) /
                    (288.0 * std::pow(n * p * rho, 2));
  const double z = -n * rho * log_w;
  const double f = p * (p + 1.0) / 2.0 - 1.0;
  const double pr1 = detail::chi2_upper_p(z, f);
  const double pr2 = detail::chi2_upper_p(z, f + 4.0);
  return {name, std::exp(log_w), std::clamp(pr1 + w2 * (pr2 - pr1), 0.0, 1.0)};
}

std::vector<PairwiseComparison> pairwise(const LongTable& table, const Design& d,
                                         const std::string& factor) {
  int f = -1;
  for (size_t i = 0; i < d.within.size(); ++i) {
    if (d.within[i].name == factor) f = static_cast<int>(i);
  }
  if (f < 0) {
    throw InputError(table.source + ": --pairwise: '" + factor +
                     "' is not one of the --within factors (paired comparisons need a "
                     "within-subject factor)");
  }
  const int n = static_cast<int>(d.y.rows());
  const int levels = d.dims[f];
  long inner = 1;
  for (size_t i = f + 1; i < d.dims.size(); ++i) inner *= d.dims[i];
  Eigen::MatrixXd means = Eigen::MatrixXd::Zero(n, levels);  // (N x L) subject mean per level
  for (long c = 0; c < d.y.cols(); ++c) means.col((c / inner) % levels) += d.y.col(c);
  means /= static_cast<double>(d.y.cols() / levels);
  std::vector<PairwiseComparison> out;
  for (int i = 0; i < levels; ++i) {
    for (int j = i + 1; j < levels; ++j) {
      PairwiseComparison pc;
      pc.factor = factor;
      pc.level1 = d.within[f].levels[i];
      pc.level2 = d.within[f].levels[j];
      const Eigen::VectorXd diff = means.col(i) - means.col(j);
      pc.mean_diff = diff.mean();
      const double var = (diff.array() - pc.mean_diff).square().sum() / (n - 1);
      pc.se = std::sqrt(var / n);
      pc.df = n - 1;
      const double scale = means.col(i).squaredNorm() + means.col(j).squaredNorm();
      pc.testable = var * (n - 1) > kZeroErrorFraction * scale;
      pc.t = pc.testable ? pc.mean_diff / pc.se : 0.0;
      pc.p = pc.testable ? detail::t_two_sided_p(pc.t, pc.df) : 1.0;
      out.push_back(pc);
    }
  }
  std::vector<double> p;
  for (const auto& pc : out) p.push_back(pc.p);
  const std::vector<double> adjusted = detail::holm(p);
  for (size_t k = 0; k < out.size(); ++k) {
    out[k].p_holm = adjusted[k];
    out[k].p_bonferroni = std::min(1.0, static_cast<double>(out.size()) * out[k].p);
  }
  return out;
}

}  // namespace

AnovaResult repeated_measures_anova(const LongTable& table,
                                    const RepeatedMeasuresOptions& options) {
  check_options(table, options);
  const Design d = build_design(table, options);
  const BetweenDesign bd = build_between(table, d);
  const int n = static_cast<int>(d.subjects.size());
  const int p_cols = static_cast<int>(bd.x.cols());
  const double error_df = n - p_cols;
  AnovaResult result;
  result.subjects = n;
  result.observations = table.row_count();
  result.averaged_cells = d.averaged_cells;
  if (d.averaged_cells > 0) {
    result.notes.push_back(std::to_string(d.averaged_cells) +
                           " subject x cell entries had several rows (" +
                           std::to_string(d.averaged_rows) + " rows) and were averaged");
  }
  const Eigen::MatrixXd xtx_inv =
      (bd.x.transpose() * bd.x).ldlt().solve(Eigen::MatrixXd::Identity(p_cols, p_cols));
  const double scale = d.y.squaredNorm();

  std::vector<std::vector<int>> within_terms{{}};
  for (const auto& t : detail::terms_by_order(static_cast<int>(d.within.size()))) {
    within_terms.push_back(t);
  }
  double error_ss_total = 0.0;  // sum of the error SS of every within term, for ges
  std::vector<std::string> zero_error, hf_skipped, mauchly_skipped;
  for (const auto& s_term : within_terms) {
    const Eigen::MatrixXd z = detail::project_term(d.y, d.dims, s_term);  // (N x d)
    const int dof = static_cast<int>(z.cols());
    const Eigen::MatrixXd b = xtx_inv * (bd.x.transpose() * z);  // (P x d)
    const Eigen::MatrixXd resid = z - bd.x * b;
    const Eigen::MatrixXd e = resid.transpose() * resid;  // (d x d)
    const double ss_error = e.trace();
    error_ss_total += ss_error;
    for (size_t t = 0; t < bd.terms.size(); ++t) {
      if (s_term.empty() && t == 0) continue;  // the grand mean
      const Eigen::MatrixXd lb = b.middleRows(bd.first_col[t], bd.col_count[t]);
      const Eigen::MatrixXd middle =
          xtx_inv.block(bd.first_col[t], bd.first_col[t], bd.col_count[t], bd.col_count[t]);
      const Eigen::MatrixXd h = lb.transpose() * middle.ldlt().solve(lb);
      AnovaEffect eff;
      for (const int f : bd.terms[t]) eff.factors.push_back(d.between[f].name);
      for (const int f : s_term) eff.factors.push_back(d.within[f].name);
      eff.name = detail::join_names(eff.factors);
      eff.type = s_term.empty() ? EffectType::between : EffectType::within;
      eff.ss = h.trace();
      eff.ss_error = ss_error;
      eff.df1 = static_cast<double>(bd.col_count[t]) * dof;
      eff.df2 = error_df * dof;
      eff.ms = eff.ss / eff.df1;
      eff.ms_error = ss_error / eff.df2;
      eff.pes = eff.ss / (eff.ss + ss_error);
      eff.testable = ss_error > kZeroErrorFraction * scale;
      if (eff.testable) {
        eff.f = eff.ms / eff.ms_error;
        eff.p = detail::f_upper_p(eff.f, eff.df1, eff.df2);
      } else {
        eff.pes.reset();
        eff.note = "zero error variance: F is undefined";
        zero_error.push_back(eff.name);
      }
      if (!s_term.empty() && eff.testable) {
        const double gg = dof == 1 ? 1.0 : e.trace() * e.trace() / (dof * (e * e).trace());
        eff.epsilon_gg = gg;
        eff.p_gg = detail::f_upper_p(eff.f, eff.df1 * gg, eff.df2 * gg);
        const double hf_den = dof * (error_df - dof * gg);
        if (hf_den > 0.0) {
          const double hf = std::min(1.0, ((error_df + 1.0) * dof * gg - 2.0) / hf_den);
          eff.epsilon_hf = hf;
          eff.p_hf = detail::f_upper_p(eff.f, eff.df1 * hf, eff.df2 * hf);
        } else {
          hf_skipped.push_back(eff.name);
        }
        if (dof > 1) {
          const Eigen::VectorXd lambda =
              Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(e, Eigen::EigenvaluesOnly)
                  .eigenvalues();
          if (error_df >= dof && lambda.minCoeff() > kSingularEigenFraction * lambda.maxCoeff()) {
            result.mauchly.push_back(
                mauchly(eff.name, e, error_df, static_cast<double>(d.y.cols())));
          } else {
            mauchly_skipped.push_back(eff.name);
          }
        }
      }
      result.effects.push_back(std::move(eff));
    }
  }
  for (auto& eff : result.effects) {
    if (eff.testable) eff.ges = eff.ss / (eff.ss + error_ss_total);
  }
  const auto list = [](const std::vector<std::string>& names) {
    std::string out;
    for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + names[i];
    return out;
  };
  if (!mauchly_skipped.empty()) {
    result.notes.push_back(
        "Mauchly's test skipped for " + list(mauchly_skipped) + ": its error matrix is singular (" +
        std::to_string(n) + " subjects give " + std::to_string(static_cast<int>(error_df)) +
        " error df per contrast, fewer than the effect's contrasts, or the errors are collinear)");
  }
  if (!hf_skipped.empty()) {
    result.notes.push_back("Huynh-Feldt epsilon undefined for " + list(hf_skipped) +
                           ": too few subjects for its formula (N - g <= df1 * epsilon_GG)");
  }
  for (const auto& factor : options.pairwise) {
    for (auto& pc : pairwise(table, d, factor)) {
      if (!pc.testable) {
        zero_error.push_back("pairwise " + pc.factor + " " + pc.level1 + "-" + pc.level2);
      }
      result.pairwise.push_back(std::move(pc));
    }
  }
  if (!zero_error.empty()) {
    result.status = Status::failure(
        "zero error variance for " + list(zero_error) +
        ": every subject shows exactly the same differences between cells, so F (or t) is "
        "undefined");
  }
  return result;
}

}  // namespace stiffid::validation
