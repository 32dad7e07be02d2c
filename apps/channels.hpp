#pragma once
// Checks on the channel lists a subcommand is given (--inputs, --outputs).

#include <string>
#include <vector>

namespace stiffid::apps {

/// Throws InputError when a channel appears twice across --inputs and --outputs.
void check_distinct(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs);

}  // namespace stiffid::apps
