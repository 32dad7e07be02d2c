#pragma once
// Checks on the channel lists a subcommand is given (--inputs, --outputs).

#include <string>
#include <vector>

#include "data/csv.hpp"

namespace stiffid::apps {

/// Throws InputError when a channel appears twice across --inputs and --outputs.
void check_distinct(const std::vector<std::string>& inputs,
                    const std::vector<std::string>& outputs);

/// CSV options of a trial read with `--fs sample_rate_hz` (Hz; 0: from the t column); throws
/// InputError naming --fs when it is negative or not finite.
data::TrialCsvOptions trial_csv_options(double sample_rate_hz);

}  // namespace stiffid::apps
