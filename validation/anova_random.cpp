// Classical ANOVA of a balanced crossed design with fixed and random factors: expected mean
// squares by the Cornfield-Tukey rules, exact F or quasi-F with Satterthwaite df.

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>

#include "validation/anova.hpp"
#include "validation/anova_detail.hpp"

namespace stiffid::validation {
namespace {

// A denominator mean square at or below this fraction of mean(y^2) is zero: its round-off floor is
// about (cells * 2.2e-16)^2 of that scale (see anova_within.cpp), measured data sit far above.
constexpr double kZeroMsFraction = 1e-20;
// A synthesized denominator sum c_j MS_j within this fraction of sum |c_j MS_j| of zero is a
// cancellation, not a variance estimate (relative round-off of a few additions is ~1e-15).
constexpr double kCancellationFraction = 1e-12;
// The EMS system has 0/1 entries and integer solutions; a least-squares residual above this means
// no combination of mean squares has the null expectation.
constexpr double kEmsSolveTolerance = 1e-9;

bool is_subset(const std::vector<int>& a, const std::vector<int>& b) {
  return std::includes(b.begin(), b.end(), a.begin(), a.end());
}

}  // namespace

AnovaResult mixed_model_anova(const LongTable& table, const MixedAnovaOptions& options) {
  std::vector<std::string> names = options.fixed;
  names.insert(names.end(), options.random.begin(), options.random.end());
  if (names.empty()) {
    throw InputError(table.source + ": --fixed/--random: at least one factor is needed");
  }
  std::set<std::string> seen;
  for (const auto& name : names) {
    if (!seen.insert(name).second) {
      throw InputError(table.source + ": '" + name + "' is given twice among --fixed and --random");
    }
  }
  const int k = static_cast<int>(names.size());
  const int first_random = static_cast<int>(options.fixed.size());
  std::vector<FactorCoding> factors;
  for (int f = 0; f < k; ++f) {
    factors.push_back(code_factor(table, names[f], f < first_random ? "--fixed" : "--random"));
  }
  std::vector<int> dims;
  long cells = 1;
  for (const auto& f : factors) {
    dims.push_back(f.level_count());
    cells *= f.level_count();
  }
  std::vector<int> count(cells, 0), first_row(cells, -1);
  Eigen::MatrixXd sum = Eigen::MatrixXd::Zero(1, cells);
  std::vector<long> cell_of(table.row_count());
  for (int r = 0; r < table.row_count(); ++r) {
    long cell = 0;
    for (const auto& f : factors) cell = cell * f.level_count() + f.codes[r];
    cell_of[r] = cell;
    sum(0, cell) += table.values[r];
    if (count[cell]++ == 0) first_row[cell] = r;
  }
  const auto label = [&](long cell) {
    std::vector<std::string> parts(k);
    for (int f = k - 1; f >= 0; --f) {
      parts[f] = factors[f].name + "=" + factors[f].levels[cell % dims[f]];
      cell /= dims[f];
    }
    std::string out;
    for (int f = 0; f < k; ++f) out += (f ? ", " : "") + parts[f];
    return out;
  };
  const int n = count[0] > 0 ? count[0] : *std::max_element(count.begin(), count.end());
  for (long c = 0; c < cells; ++c) {
    if (count[c] == 0) {
      const long missing = std::count(count.begin(), count.end(), 0);
      throw InputError(table.source + ": no observation for cell " + label(c) +
                       "; the mixed-model ANOVA needs every combination of --fixed and --random "
                       "levels (" +
                       std::to_string(missing) + " of " + std::to_string(cells) +
                       " cells missing)");
    }
    if (count[c] != n) {
      throw InputError(table.source + ": unbalanced design: cell " + label(c) + " (first row at " +
                       table.where(first_row[c]) + ") has " + std::to_string(count[c]) +
                       " observations but cell " + label(0) + " has " + std::to_string(n) +
                       "; the classical mixed-model ANOVA needs the same count in every cell");
    }
  }
  const Eigen::MatrixXd mean = sum / static_cast<double>(n);  // (1 x C) cell means
  double ss_resid = 0.0, scale = 0.0;
  for (int r = 0; r < table.row_count(); ++r) {
    ss_resid += std::pow(table.values[r] - mean(0, cell_of[r]), 2);
    scale += table.values[r] * table.values[r];
  }
  scale /= table.row_count();

  AnovaResult result;
  result.observations = table.row_count();
  result.replicates = n;
  const std::vector<std::vector<int>> terms = detail::terms_by_order(k);
  const int t_count = static_cast<int>(terms.size());
  std::vector<double> ss(t_count), df(t_count);
  for (int t = 0; t < t_count; ++t) {
    ss[t] = n * detail::project_term(mean, dims, terms[t]).squaredNorm();
    df[t] = 1.0;
    for (const int f : terms[t]) df[t] *= dims[f] - 1;
  }
  const auto term_name = [&](int t) {
    std::vector<std::string> parts;
    for (const int f : terms[t]) parts.push_back(names[f]);
    return detail::join_names(parts);
  };
  const auto has_random = [&](const std::vector<int>& term) {
    return std::any_of(term.begin(), term.end(), [&](int f) { return f >= first_random; });
  };

  // Mean squares: every term, plus the within-cell residual when n >= 2. With n = 1 the highest
  // interaction (the last term) is the residual.
  const bool replicated = n >= 2;
  std::vector<double> ms, ms_df;
  std::vector<std::string> ms_name;
  for (int t = 0; t < t_count; ++t) {
    ms.push_back(ss[t] / df[t]);
    ms_df.push_back(df[t]);
    ms_name.push_back(!replicated && t == t_count - 1 ? "residual" : term_name(t));
  }
  if (replicated) {
    const double df_resid = static_cast<double>(cells) * (n - 1);
    ms.push_back(ss_resid / df_resid);
    ms_df.push_back(df_resid);
    ms_name.push_back("residual");
  }
  const int m_count = static_cast<int>(ms.size());
  // EMS incidence (components x mean squares): component t (term variance or fixed quadratic form)
  // or the error variance (last row) enters EMS(MS_g). The coefficient n prod_{f not in t} L_f of a
  // component is the same in every EMS it enters, so 0/1 incidence carries the whole algebra.
  Eigen::MatrixXd ems = Eigen::MatrixXd::Zero(t_count + 1, m_count);
  for (int g = 0; g < m_count; ++g) {
    ems(t_count, g) = 1.0;
    if (g >= t_count) continue;  // residual: error variance only
    for (int t = 0; t < t_count; ++t) {
      if (!is_subset(terms[g], terms[t])) continue;
      bool enters = t == g;
      if (!enters && options.model == MixedModel::unrestricted) enters = has_random(terms[t]);
      if (!enters && options.model == MixedModel::restricted) {
        enters = std::all_of(terms[t].begin(), terms[t].end(), [&](int f) {
          return f >= first_random ||
                 std::find(terms[g].begin(), terms[g].end(), f) != terms[g].end();
        });
      }
      if (enters) ems(t, g) = 1.0;
    }
  }
  if (!replicated) {
    // One observation per cell: the highest interaction cannot be told from the error, so its
    // component is merged into the error variance. Exact in the unrestricted model (the highest
    // interaction is random and enters every EMS); in the restricted model it assumes that
    // interaction away where the model would exclude it (the usual no-interaction assumption).
    ems.row(t_count - 1).setZero();
  }
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> solver(ems);
  std::vector<std::string> failed, no_test;
  const int tested = replicated ? t_count : t_count - 1;
  for (int t = 0; t < tested; ++t) {
    AnovaEffect eff;
    for (const int f : terms[t]) eff.factors.push_back(names[f]);
    eff.name = term_name(t);
    eff.type = has_random(terms[t]) ? EffectType::random : EffectType::fixed;
    eff.ss = ss[t];
    eff.df1 = df[t];
    eff.ms = ms[t];
    Eigen::VectorXd null_ems = ems.col(t);
    null_ems(t) = 0.0;
    Eigen::VectorXd c = solver.solve(null_ems);
    if ((ems * c - null_ems).norm() > kEmsSolveTolerance) {
      eff.testable = false;
      eff.note = "no mean square or combination of mean squares has the null expectation of " +
                 eff.name + " under the " +
                 (options.model == MixedModel::restricted ? "restricted" : "unrestricted") +
                 " model";
      no_test.push_back(eff.name);
      result.effects.push_back(std::move(eff));
      continue;
    }
    double den = 0.0, abs_sum = 0.0, satterthwaite = 0.0;
    int terms_used = 0, used = -1;
    bool unit = true;  // every coefficient is +1
    std::string text;
    for (int g = 0; g < m_count; ++g) {
      const double coef = std::round(c(g));
      if (coef == 0.0) continue;
      ++terms_used;
      used = g;
      unit = unit && coef == 1.0;
      den += coef * ms[g];
      abs_sum += std::fabs(coef * ms[g]);
      satterthwaite += std::pow(coef * ms[g], 2) / ms_df[g];
      const std::string times =
          std::fabs(coef) == 1.0 ? "" : std::to_string(static_cast<int>(std::fabs(coef))) + " ";
      text += text.empty() ? (coef < 0 ? "-" + times : times) : (coef < 0 ? " - " : " + ") + times;
      text += ms_name[g];
    }
    eff.denominator = text;
    eff.quasi = terms_used != 1 || !unit;
    eff.ms_error = den;
    eff.df2 = eff.quasi ? den * den / satterthwaite : ms_df[used];
    eff.ss_error = den * eff.df2;
    if (den <= kZeroMsFraction * scale || den <= kCancellationFraction * abs_sum) {
      eff.testable = false;
      eff.df2 = 0.0;
      eff.ss_error = 0.0;
      eff.note = eff.quasi ? "the synthesized denominator " + text + " is not positive"
                           : "zero error variance in " + text + ": F is undefined";
      failed.push_back(eff.name + " (" + eff.note + ")");
    } else {
      eff.f = eff.ms / den;
      eff.p = detail::f_upper_p(eff.f, eff.df1, eff.df2);
    }
    result.effects.push_back(std::move(eff));
  }
  if (!replicated) {
    result.notes.push_back("one observation per cell: the highest interaction " +
                           term_name(t_count - 1) + " serves as the residual and is not tested" +
                           (options.model == MixedModel::restricted
                                ? " (restricted model: its variance is assumed to be zero where "
                                  "the model would exclude it)"
                                : ""));
  }
  for (const auto& name : no_test) {
    result.notes.push_back(name + " is not testable: no denominator matches its null expectation");
  }
  if (!failed.empty()) {
    std::string msg = "effects that cannot be tested on these data: ";
    for (size_t i = 0; i < failed.size(); ++i) msg += (i ? "; " : "") + failed[i];
    result.status = Status::failure(msg);
  }
  return result;
}

}  // namespace stiffid::validation
