#include "apps/channels.hpp"

#include <set>

#include "data/error.hpp"

namespace stiffid::apps {

void check_distinct(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs) {
  std::set<std::string> seen;
  for (const auto* list : {&inputs, &outputs}) {
    for (const auto& name : *list) {
      if (!seen.insert(name).second) {
        throw InputError("--inputs/--outputs: channel '" + name + "' is listed more than once");
      }
    }
  }
}

}  // namespace stiffid::apps
