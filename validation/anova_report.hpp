#pragma once
// Reports of an ANOVA result: the JSON document of `stiffid anova` and an APA-like text table.

#include <nlohmann/json.hpp>
#include <string>

#include "validation/anova.hpp"

namespace stiffid::validation {

/// JSON of a result (schema in docs/anova.md): {"effects": [{"effect", "type", "df1", "df2", "F",
/// "p", "pes", "ges", "epsilon_gg", "p_gg", "epsilon_hf", "p_hf", "denominator", "quasi", ...}],
/// "mauchly": [{"effect", "W", "p"}], "pairwise": [{"factor", "level1", "level2", "mean_diff",
/// "se", "t", "df", "p", "p_holm", "p_bonferroni"}], ...}. Keys that do not apply are omitted
/// (no F/p for an untestable effect, no mauchly/pairwise when empty).
nlohmann::json anova_to_json(const AnovaResult& result);

/// APA-like table: one line per effect (df, F, p, effect sizes, corrections or denominator), then
/// Mauchly's tests and pairwise comparisons (result.notes are left to the caller). `title` heads
/// the table.
std::string format_anova_table(const AnovaResult& result, const std::string& title);

}  // namespace stiffid::validation
