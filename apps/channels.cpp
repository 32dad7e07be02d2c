#include "apps/channels.hpp"

#include <cmath>
#include <set>

#include "data/error.hpp"

namespace stiffid::apps {

void check_distinct(const std::vector<std::string>& inputs,
                    const std::vector<std::string>& outputs) {
  std::set<std::string> seen;
  for (const auto* list : {&inputs, &outputs}) {
    for (const auto& name : *list) {
      if (!seen.insert(name).second) {
        throw InputError("--inputs/--outputs: channel '" + name + "' is listed more than once");
      }
    }
  }
}

data::TrialCsvOptions trial_csv_options(double sample_rate_hz) {
  if (sample_rate_hz < 0.0 || !std::isfinite(sample_rate_hz)) {
    throw InputError("--fs: expected a positive sampling rate in Hz");
  }
  data::TrialCsvOptions csv;
  csv.sample_rate_hz = sample_rate_hz;
  return csv;
}

}  // namespace stiffid::apps
