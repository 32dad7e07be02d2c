#pragma once
// Declarative JSON trial specs for `stiffid simulate` (format in docs/simulator.md). Every key
// carries its unit as a suffix ("duration_s", "stiffness_nm_per_rad"); an unknown key, a key with
// a wrong or unknown unit, or an impossible value throws InputError naming the key path, e.g.
// "spec.json: viscoelasticity.stiffness_n_per_m: wrong unit for the arm model, expected
// stiffness_nm_per_rad".

#include <nlohmann/json.hpp>
#include <string>

#include "models/simulate.hpp"

namespace stiffid::models {

/// A TrialSpec from a parsed JSON object; `source` (a file name) prefixes error messages.
TrialSpec parse_trial_spec(const nlohmann::json& spec, const std::string& source);
/// Reads and parses a JSON spec file (InputError with line/column on a JSON syntax error).
TrialSpec read_trial_spec(const std::string& path);
/// The spec as JSON in the same format (parse_trial_spec(trial_spec_to_json(s)) == s).
nlohmann::json trial_spec_to_json(const TrialSpec& spec);

}  // namespace stiffid::models
