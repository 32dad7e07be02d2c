#pragma once
// Repeated-measures and classical mixed-model ANOVA, as R's afex/car (repeated measures) and the
// Cornfield-Tukey expected-mean-square tables of SPSS GLM (random factors) compute them. Used to
// ask whether estimation methods differ (Piovesan et al. 2012, Tables 2-4 and 6-9).
//
// Formulas and sources: docs/anova.md.

#include <optional>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "validation/anova_table.hpp"

namespace stiffid::validation {

/// How an effect's levels vary: within subjects, between subjects (repeated-measures design), or
/// a fixed / random effect of the classical mixed model.
enum class EffectType { within, between, fixed, random };
const char* to_string(EffectType type);

/// One row of an ANOVA table.
struct AnovaEffect {
  std::string name;                  ///< factor names joined by ':' ("group:method:noise")
  std::vector<std::string> factors;  ///< factors of the effect, in the order given
  EffectType type = EffectType::within;
  double ss = 0.0;        ///< sum of squares of the effect, (dv unit)^2
  double ss_error = 0.0;  ///< sum of squares of its error term ((dv unit)^2); for a quasi-F, the
                          ///< synthesized denominator times df2
  double df1 = 0.0;       ///< numerator degrees of freedom
  double df2 = 0.0;       ///< denominator degrees of freedom (Satterthwaite for a quasi-F)
  double ms = 0.0;        ///< ss / df1
  double ms_error = 0.0;  ///< denominator mean square
  bool testable = true;   ///< false: f and p are meaningless and `note` says why
  double f = 0.0;         ///< F = ms / ms_error
  double p = 1.0;         ///< P(F(df1, df2) > f), from the complement of the CDF
  std::optional<double> pes;         ///< partial eta squared ss / (ss + ss_error)
  std::optional<double> ges;         ///< generalized eta squared (Olejnik & Algina 2003, all
                                     ///< factors manipulated, as afex)
  std::optional<double> epsilon_gg;  ///< Greenhouse-Geisser epsilon (within effects)
  std::optional<double> p_gg;        ///< p with df1, df2 scaled by epsilon_gg
  std::optional<double> epsilon_hf;  ///< Huynh-Feldt epsilon, car's formula capped at 1
  std::optional<double> p_hf;        ///< p with df1, df2 scaled by epsilon_hf
  std::string denominator;           ///< mixed model: the mean square(s) of the F denominator, e.g.
                                     ///< "residual", "method:kprofile" or "a:b + a:c - a:b:c"
  bool quasi = false;  ///< mixed model: the denominator is a synthesized (quasi-F) one
  std::string note;    ///< why the effect is not testable, or a caveat ("" when none)
};

/// Mauchly's test of sphericity for a within effect with more than 2 levels (df1 / df_between > 1).
struct MauchlyTest {
  std::string effect;  ///< effect name as in AnovaEffect::name
  double w = 1.0;      ///< Mauchly's W in (0, 1]
  double p = 1.0;      ///< p of the chi-squared approximation with Anderson's correction (R's
                       ///< mauchly.test / car)
};

/// A paired t-test between two levels of a within factor, on each subject's mean per level.
struct PairwiseComparison {
  std::string factor;
  std::string level1, level2;  ///< level1 precedes level2 in order of first appearance
  double mean_diff = 0.0;      ///< mean over subjects of (mean at level1 - mean at level2)
  double se = 0.0;             ///< standard error of mean_diff, sd / sqrt(n)
  double t = 0.0;              ///< mean_diff / se
  double df = 0.0;             ///< n - 1, n subjects
  double p = 1.0;              ///< two-sided p, uncorrected
  double p_holm = 1.0;         ///< Holm step-down adjusted over the factor's pairs
  double p_bonferroni = 1.0;   ///< min(1, m p), m pairs of the factor
  bool testable = true;        ///< false when the differences have zero variance
};

struct AnovaResult {
  Status status;                             ///< failure when an effect cannot be tested
                                             ///< because of the data (zero error variance, a
                                             ///< non-positive synthesized denominator)
  std::vector<AnovaEffect> effects;          ///< in R's term order (see docs/anova.md)
  std::vector<MauchlyTest> mauchly;          ///< within effects with more than one df per subject
  std::vector<PairwiseComparison> pairwise;  ///< requested factors, pairs in level order
  int subjects = 0;                          ///< subjects (repeated measures) or 0 (mixed model)
  int observations = 0;                      ///< rows read
  int averaged_cells = 0;  ///< subject x cell (or design cell) entries that had several rows
                           ///< and were averaged
  int replicates = 0;      ///< mixed model: observations per design cell
  std::vector<std::string> notes;  ///< things a user should know (averaging, skipped tests)
};

struct RepeatedMeasuresOptions {
  std::string subject;                ///< subject column
  std::vector<std::string> within;    ///< within-subject factors (each subject sees every cell)
  std::vector<std::string> between;   ///< between-subject factors (constant per subject)
  std::vector<std::string> pairwise;  ///< within factors whose level pairs are compared
};

/// Univariate repeated-measures ANOVA with any number of within and between factors.
///
/// Cell means Y (N subjects x C within cells, several rows per cell averaged) are projected on
/// orthonormal contrasts M_S (C x d_S, Kronecker products of per-factor Helmert contrasts) per
/// within term S, Z_S = Y M_S (N x d_S). With the between design X (N x P, sum-to-zero coding,
/// full factorial) the error SSP is E_S = Z_S' (I - X (X'X)^-1 X') Z_S (d_S x d_S) and the type III
/// hypothesis SSP of between term T is H = (L B)' (L (X'X)^-1 L')^-1 (L B), B = (X'X)^-1 X' Z_S.
/// SS = tr H, SS_error = tr E, df1 = df_T d_S, df2 = (N - P) d_S (as car::Anova, type III).
/// GG epsilon = tr(E)^2 / (d tr(E^2)); HF = ((N-P+1) d GG - 2) / (d (N-P - d GG)) capped at 1.
/// Throws InputError on a bad design (missing cell, single level, too few subjects).
AnovaResult repeated_measures_anova(const LongTable& table, const RepeatedMeasuresOptions& options);

enum class MixedModel {
  unrestricted,  ///< interaction components enter the EMS of every contained effect (SPSS, lme4)
  restricted     ///< ... only when the other factors of the interaction are all random
};

struct MixedAnovaOptions {
  std::vector<std::string> fixed;   ///< fixed factors
  std::vector<std::string> random;  ///< random factors
  MixedModel model = MixedModel::unrestricted;
};

/// Classical ANOVA of a balanced, fully crossed design with fixed and random factors and n >= 1
/// observations per cell. Expected mean squares by the Cornfield-Tukey rules; each effect is
/// tested against the mean square matching its null expectation, or against the quasi-F
/// denominator sum_j c_j MS_j (c_j = +-1) with Satterthwaite df2 = (sum c_j MS_j)^2 /
/// sum (c_j MS_j)^2 / df_j. With n = 1 the highest interaction is the residual and is not tested.
/// Throws InputError on a missing or unbalanced cell or a single-level factor.
AnovaResult mixed_model_anova(const LongTable& table, const MixedAnovaOptions& options);

}  // namespace stiffid::validation
