#include "validation/anova_report.hpp"

#include <cstdio>
#include <sstream>

namespace stiffid::validation {
namespace {

void put(nlohmann::json& j, const char* key, const std::optional<double>& value) {
  if (value) j[key] = *value;
}

// APA style: three decimals without the leading zero, "< .001" below.
std::string apa_p(double p) {
  if (p < 0.001) return "< .001";
  char buffer[16];
  std::snprintf(buffer, sizeof buffer, "%.3f", p);
  std::string s = buffer;
  return s[0] == '0' ? s.substr(1) : s;
}

std::string fixed(double value, int decimals) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*f", decimals, value);
  return buffer;
}

std::string opt(const std::optional<double>& value, int decimals) {
  return value ? fixed(*value, decimals) : "";
}

std::string opt_p(const std::optional<double>& value) { return value ? apa_p(*value) : ""; }

std::string pad(const std::string& s, size_t width) {
  return s.size() >= width ? s + " " : s + std::string(width - s.size(), ' ');
}

}  // namespace

nlohmann::json anova_to_json(const AnovaResult& result) {
  nlohmann::json out;
  out["effects"] = nlohmann::json::array();
  for (const auto& e : result.effects) {
    nlohmann::json j;
    j["effect"] = e.name;
    j["type"] = to_string(e.type);
    j["df1"] = e.df1;
    if (e.df2 > 0.0) j["df2"] = e.df2;
    if (e.testable) {
      j["F"] = e.f;
      j["p"] = e.p;
    }
    put(j, "pes", e.pes);
    put(j, "ges", e.ges);
    put(j, "epsilon_gg", e.epsilon_gg);
    put(j, "p_gg", e.p_gg);
    put(j, "epsilon_hf", e.epsilon_hf);
    put(j, "p_hf", e.p_hf);
    j["ss"] = e.ss;
    j["ms"] = e.ms;
    if (e.testable) j["ms_error"] = e.ms_error;
    if (e.type == EffectType::fixed || e.type == EffectType::random) {
      if (!e.denominator.empty()) {
        j["denominator"] = e.denominator;
        j["quasi"] = e.quasi;
      }
    }
    if (!e.note.empty()) j["note"] = e.note;
    out["effects"].push_back(std::move(j));
  }
  if (!result.mauchly.empty()) {
    out["mauchly"] = nlohmann::json::array();
    for (const auto& m : result.mauchly) {
      out["mauchly"].push_back({{"effect", m.effect}, {"W", m.w}, {"p", m.p}});
    }
  }
  if (!result.pairwise.empty()) {
    out["pairwise"] = nlohmann::json::array();
    for (const auto& pc : result.pairwise) {
      nlohmann::json j{{"factor", pc.factor},       {"level1", pc.level1}, {"level2", pc.level2},
                       {"mean_diff", pc.mean_diff}, {"se", pc.se},         {"df", pc.df}};
      if (pc.testable) {
        j["t"] = pc.t;
        j["p"] = pc.p;
        j["p_holm"] = pc.p_holm;
        j["p_bonferroni"] = pc.p_bonferroni;
      }
      out["pairwise"].push_back(std::move(j));
    }
  }
  out["observations"] = result.observations;
  if (result.subjects > 0) out["subjects"] = result.subjects;
  if (result.replicates > 0) out["replicates"] = result.replicates;
  out["averaged_cells"] = result.averaged_cells;
  out["notes"] = result.notes;
  return out;
}

std::string format_anova_table(const AnovaResult& result, const std::string& title) {
  std::ostringstream out;
  out << title << "\n";
  size_t width = 8;
  for (const auto& e : result.effects) width = std::max(width, e.name.size() + 2);
  const bool mixed = !result.effects.empty() && (result.effects[0].type == EffectType::fixed ||
                                                 result.effects[0].type == EffectType::random);
  out << pad("Effect", width) << pad("df1", 7) << pad("df2", 9) << pad("F", 10) << pad("p", 8);
  if (mixed) {
    out << pad("type", 8) << "denominator\n";
  } else {
    out << pad("pes", 7) << pad("ges", 7) << pad("eps_GG", 8) << pad("p_GG", 8) << pad("eps_HF", 8)
        << "p_HF\n";
  }
  for (const auto& e : result.effects) {
    out << pad(e.name, width) << pad(fixed(e.df1, 0), 7);
    if (e.testable) {
      out << pad(fixed(e.df2, e.quasi ? 2 : 0), 9) << pad(fixed(e.f, 3), 10) << pad(apa_p(e.p), 8);
    } else {
      out << pad("-", 9) << pad("-", 10) << pad("-", 8);
    }
    if (mixed) {
      out << pad(to_string(e.type), 8) << (e.quasi ? "quasi: " : "") << e.denominator;
    } else {
      out << pad(opt(e.pes, 3), 7) << pad(opt(e.ges, 3), 7) << pad(opt(e.epsilon_gg, 3), 8)
          << pad(opt_p(e.p_gg), 8) << pad(opt(e.epsilon_hf, 3), 8) << opt_p(e.p_hf);
    }
    if (!e.note.empty()) out << "  (" << e.note << ")";
    out << "\n";
  }
  if (!result.mauchly.empty()) {
    out << "\nMauchly's test of sphericity\n" << pad("Effect", width) << pad("W", 8) << "p\n";
    for (const auto& m : result.mauchly) {
      out << pad(m.effect, width) << pad(fixed(m.w, 3), 8) << apa_p(m.p) << "\n";
    }
  }
  if (!result.pairwise.empty()) {
    out << "\nPairwise paired t-tests on subject means\n"
        << pad("Factor", 10) << pad("Pair", 24) << pad("diff", 10) << pad("se", 9) << pad("t", 9)
        << pad("df", 5) << pad("p", 8) << pad("p_holm", 8) << "p_bonf\n";
    for (const auto& pc : result.pairwise) {
      out << pad(pc.factor, 10) << pad(pc.level1 + " - " + pc.level2, 24)
          << pad(fixed(pc.mean_diff, 4), 10) << pad(fixed(pc.se, 4), 9)
          << pad(pc.testable ? fixed(pc.t, 3) : "-", 9) << pad(fixed(pc.df, 0), 5)
          << pad(pc.testable ? apa_p(pc.p) : "-", 8) << pad(pc.testable ? apa_p(pc.p_holm) : "-", 8)
          << (pc.testable ? apa_p(pc.p_bonferroni) : "-") << "\n";
    }
  }
  return out.str();
}

}  // namespace stiffid::validation
