// The registries of built-in cell evaluators and reporters: the one place that lists them.
#include "validation/perreault1999.hpp"
#include "validation/study.hpp"

namespace stiffid::validation {

EvaluatorRegistry builtin_evaluators() {
  EvaluatorRegistry registry;
  registry.add("synthetic", synthetic_evaluator,
               "seeded normal draws, no physics (tests and demonstrations of the runner)");
  registry.add("mimo_identification", mimo_identification_evaluator,
               "simulated endpoint or arm trial, MIMO FRF and IRF scored against the exact "
               "compliance (Perreault et al. 1999)");
  return registry;
}

std::map<std::string, StudyReporter> builtin_reporters() {
  return {{"summary", write_summary_report}, {"perreault1999", write_perreault1999_report}};
}

}  // namespace stiffid::validation
