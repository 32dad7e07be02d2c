#include "validation/study_spec.hpp"

#include <cstdio>
#include <limits>
#include <regex>
#include <set>

#include "data/error.hpp"
#include "data/text_input.hpp"

namespace stiffid::validation {
namespace {

using ordered = nlohmann::ordered_json;

const std::regex kNamePattern("[A-Za-z0-9_.-]+");
const std::regex kPlaceholder(R"(\$\{([^}]*)\})");

class Where {
 public:
  Where(std::string source) : source_(std::move(source)) {}
  [[noreturn]] void fail(const std::string& key, const std::string& expected) const {
    throw InputError(source_ + ": key '" + key + "': " + expected);
  }
  const std::string& source() const { return source_; }

 private:
  std::string source_;
};

void reject_unknown_keys(const ordered& object, const std::set<std::string>& known,
                         const std::string& path, const Where& where) {
  for (const auto& item : object.items()) {
    if (!known.count(item.key())) {
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      where.fail(path + item.key(), "unknown key; expected one of " + list);
    }
  }
}

std::string get_name(const ordered& object, const std::string& key, const std::string& path,
                     const Where& where) {
  if (!object.contains(key)) where.fail(path + key, "missing; expected a name");
  const auto& value = object.at(key);
  if (!value.is_string() || !std::regex_match(value.get<std::string>(), kNamePattern)) {
    where.fail(path + key,
               "expected a name of letters, digits, '_', '.' or '-', got " + value.dump());
  }
  return value.get<std::string>();
}

Design parse_design(const ordered& node, const std::string& path, const Where& where) {
  if (!node.is_object()) where.fail(path, "expected an object describing a design");
  reject_unknown_keys(node, {"name", "evaluator", "factors", "template", "metrics"}, path + "/",
                      where);
  Design design;
  design.name = get_name(node, "name", path + "/", where);
  design.evaluator = get_name(node, "evaluator", path + "/", where);
  if (node.contains("factors")) {
    const auto& factors = node.at("factors");
    if (!factors.is_object()) where.fail(path + "/factors", "expected an object {name: [levels]}");
    for (const auto& item : factors.items()) {
      const std::string key = path + "/factors/" + item.key();
      if (!std::regex_match(item.key(), kNamePattern) || item.key() == "replicate") {
        where.fail(key,
                   "expected a factor name of letters, digits, '_', '.' or '-' (not "
                   "'replicate', which is reserved)");
      }
      if (!item.value().is_array() || item.value().empty()) {
        where.fail(key, "expected a non-empty array of levels");
      }
      Factor factor{item.key(), {}};
      std::set<std::string> seen;
      for (const auto& level : item.value()) {
        const nlohmann::json plain = nlohmann::json::parse(level.dump());
        if (!seen.insert(plain.dump()).second) {
          where.fail(key, "level " + plain.dump() + " appears twice; expected distinct levels");
        }
        factor.levels.push_back(plain);
      }
      design.factors.push_back(std::move(factor));
    }
  }
  design.trial_template = node.contains("template")
                              ? nlohmann::json::parse(node.at("template").dump())
                              : nlohmann::json::object();
  if (node.contains("metrics")) {
    const auto& metrics = node.at("metrics");
    if (!metrics.is_array()) where.fail(path + "/metrics", "expected an array of metric names");
    std::set<std::string> seen;
    for (const auto& m : metrics) {
      if (!m.is_string() || m.get<std::string>().empty()) {
        where.fail(path + "/metrics", "expected metric names (strings), got " + m.dump());
      }
      if (!seen.insert(m.get<std::string>()).second) {
        where.fail(path + "/metrics", "metric '" + m.get<std::string>() + "' listed twice");
      }
      design.metrics.push_back(m.get<std::string>());
    }
  }
  return design;
}

// Placeholders must name a factor of the design or "replicate"; checked once at parse time so that
// a typo is reported before any cell runs.
void check_placeholders(const nlohmann::json& node, const Design& design, const std::string& path,
                        const Where& where) {
  if (node.is_object()) {
    for (const auto& item : node.items()) {
      check_placeholders(item.value(), design, path + "/" + item.key(), where);
    }
  } else if (node.is_array()) {
    for (std::size_t i = 0; i < node.size(); ++i) {
      check_placeholders(node[i], design, path + "/" + std::to_string(i), where);
    }
  } else if (node.is_string()) {
    const std::string text = node.get<std::string>();
    for (auto it = std::sregex_iterator(text.begin(), text.end(), kPlaceholder);
         it != std::sregex_iterator(); ++it) {
      const std::string name = (*it)[1];
      bool known = name == "replicate";
      for (const auto& f : design.factors) known = known || f.name == name;
      if (!known) {
        where.fail(path,
                   "placeholder ${" + name + "} names no factor of design '" + design.name + "'");
      }
    }
  }
}

std::string level_text(const nlohmann::json& level) {
  return level.is_string() ? level.get<std::string>() : level.dump();
}

nlohmann::json fill(const nlohmann::json& node, const nlohmann::json& values) {
  if (node.is_object()) {
    nlohmann::json out = nlohmann::json::object();
    for (const auto& item : node.items()) out[item.key()] = fill(item.value(), values);
    return out;
  }
  if (node.is_array()) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& item : node) out.push_back(fill(item, values));
    return out;
  }
  if (!node.is_string()) return node;
  const std::string text = node.get<std::string>();
  std::smatch whole;
  if (std::regex_match(text, whole, kPlaceholder)) return values.at(std::string(whole[1]));
  std::string out;
  auto last = text.cbegin();
  for (auto it = std::sregex_iterator(text.begin(), text.end(), kPlaceholder);
       it != std::sregex_iterator(); ++it) {
    out.append(last, text.cbegin() + it->position());
    out += level_text(values.at(std::string((*it)[1])));
    last = text.cbegin() + it->position() + it->length();
  }
  out.append(last, text.cend());
  return out;
}

}  // namespace

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

std::uint64_t fnv1a64(const std::string& bytes) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (unsigned char c : bytes) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::string hex64(std::uint64_t value) {
  char buffer[17];
  std::snprintf(buffer, sizeof buffer, "%016llx", static_cast<unsigned long long>(value));
  return buffer;
}

nlohmann::json StudySpec::to_json() const {
  nlohmann::json designs_json = nlohmann::json::array();
  for (const auto& d : designs) {
    // Factors as an array of {name, levels}: canonical JSON sorts object keys, and factor order
    // matters (it sets the cell order).
    nlohmann::json factors = nlohmann::json::array();
    for (const auto& f : d.factors) factors.push_back({{"name", f.name}, {"levels", f.levels}});
    designs_json.push_back({{"name", d.name},
                            {"evaluator", d.evaluator},
                            {"factors", factors},
                            {"template", d.trial_template},
                            {"metrics", d.metrics}});
  }
  return {{"name", name},
          {"seed", seed},
          {"replicates", replicates},
          {"report", report},
          {"designs", designs_json}};
}

std::string StudySpec::hash() const { return hex64(fnv1a64(to_json().dump())); }

std::vector<std::string> StudySpec::factor_names() const {
  std::vector<std::string> names;
  for (const auto& d : designs) {
    for (const auto& f : d.factors) {
      if (std::find(names.begin(), names.end(), f.name) == names.end()) names.push_back(f.name);
    }
  }
  return names;
}

StudySpec parse_study_spec(const std::string& text, const std::string& source) {
  const Where where(source);
  const ordered root = data::parse_json_text<ordered>(text, source);
  if (!root.is_object()) where.fail("(root)", "expected a JSON object");
  reject_unknown_keys(root, {"name", "description", "seed", "replicates", "report", "designs"}, "",
                      where);
  StudySpec spec;
  spec.source = source;
  spec.name = get_name(root, "name", "", where);
  if (root.contains("seed")) {
    const auto& seed = root.at("seed");
    if (!seed.is_number_unsigned()) {
      where.fail("seed", "expected a non-negative integer, got " + seed.dump());
    }
    spec.seed = seed.get<std::uint64_t>();
  }
  if (root.contains("replicates")) {
    const auto& r = root.at("replicates");
    if (!r.is_number_integer() || r.get<std::int64_t>() < 1 || r.get<std::int64_t>() > 1000000) {
      where.fail("replicates", "expected an integer in [1, 1000000], got " + r.dump());
    }
    spec.replicates = r.get<int>();
  }
  if (root.contains("report")) spec.report = get_name(root, "report", "", where);
  if (!root.contains("designs") || !root.at("designs").is_array() || root.at("designs").empty()) {
    where.fail("designs", "expected a non-empty array of designs");
  }
  std::set<std::string> names;
  for (std::size_t i = 0; i < root.at("designs").size(); ++i) {
    const std::string path = "designs/" + std::to_string(i);
    Design design = parse_design(root.at("designs")[i], path, where);
    if (!names.insert(design.name).second) {
      where.fail(path + "/name", "design name '" + design.name + "' is used twice");
    }
    check_placeholders(design.trial_template, design, path + "/template", where);
    spec.designs.push_back(std::move(design));
  }
  return spec;
}

StudySpec read_study_spec(const std::string& path) {
  return parse_study_spec(data::read_text_file(path), path);
}

std::uint64_t cell_seed(std::uint64_t study_seed, const std::string& design,
                        const nlohmann::json& levels, int replicate) {
  const nlohmann::json identity = {
      {"design", design}, {"levels", levels}, {"replicate", replicate}};
  return splitmix64(splitmix64(study_seed) ^ fnv1a64(identity.dump()));
}

std::vector<Cell> enumerate_cells(const StudySpec& spec) {
  std::vector<Cell> cells;
  for (int d = 0; d < static_cast<int>(spec.designs.size()); ++d) {
    const Design& design = spec.designs[d];
    std::vector<std::size_t> digit(design.factors.size(), 0);
    while (true) {
      nlohmann::json levels = nlohmann::json::object();
      for (std::size_t f = 0; f < design.factors.size(); ++f) {
        levels[design.factors[f].name] = design.factors[f].levels[digit[f]];
      }
      for (int r = 0; r < spec.replicates; ++r) {
        Cell cell;
        cell.index = static_cast<int>(cells.size());
        cell.design = d;
        cell.levels = levels;
        cell.replicate = r;
        cell.seed = cell_seed(spec.seed, design.name, levels, r);
        cells.push_back(std::move(cell));
      }
      // Odometer with the last factor fastest.
      int f = static_cast<int>(design.factors.size()) - 1;
      while (f >= 0 && ++digit[f] == design.factors[f].levels.size()) digit[f--] = 0;
      if (f < 0) break;
    }
  }
  return cells;
}

nlohmann::json fill_template(const Design& design, const Cell& cell) {
  nlohmann::json values = cell.levels;
  values["replicate"] = cell.replicate;
  return fill(design.trial_template, values);
}

}  // namespace stiffid::validation
