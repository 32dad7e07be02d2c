#include "validation/study_keys.hpp"

#include <algorithm>
#include <cmath>

#include "data/error.hpp"

namespace stiffid::validation {

SpecKeys::SpecKeys(const nlohmann::json& spec, std::string where)
    : spec_(spec), where_(std::move(where)) {
  if (!spec_.is_object()) {
    throw InputError(where_ + ": expected a JSON object as trial spec, got " + spec_.dump());
  }
}

void SpecKeys::fail(const std::string& key, const std::string& expected) const {
  const std::string got = spec_.contains(key) ? ", got " + spec_.at(key).dump() : " (missing)";
  throw InputError(where_ + " key '" + key + "': expected " + expected + got);
}

bool SpecKeys::has(const std::string& key) const { return spec_.contains(key); }

double SpecKeys::number(const std::string& key, double fallback, double low, double high) {
  if (!has(key)) {
    read_.insert(key);
    return fallback;
  }
  return number(key, low, high);
}

double SpecKeys::number(const std::string& key, double low, double high) {
  read_.insert(key);
  const std::string range =
      "a number in [" + std::to_string(low) + ", " + std::to_string(high) + "]";
  if (!has(key) || !spec_.at(key).is_number()) fail(key, range);
  const double value = spec_.at(key).get<double>();
  if (!std::isfinite(value) || value < low || value > high) fail(key, range);
  return value;
}

long SpecKeys::integer(const std::string& key, long fallback, long low, long high) {
  read_.insert(key);
  if (!has(key)) return fallback;
  const std::string range =
      "an integer in [" + std::to_string(low) + ", " + std::to_string(high) + "]";
  if (!spec_.at(key).is_number_integer()) fail(key, range);
  const long value = spec_.at(key).get<long>();
  if (value < low || value > high) fail(key, range);
  return value;
}

bool SpecKeys::boolean(const std::string& key, bool fallback) {
  read_.insert(key);
  if (!has(key)) return fallback;
  if (!spec_.at(key).is_boolean()) fail(key, "true or false");
  return spec_.at(key).get<bool>();
}

std::string SpecKeys::choice(const std::string& key, const std::string& fallback,
                             const std::vector<std::string>& choices) {
  read_.insert(key);
  if (!has(key)) return fallback;
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "" : "|") + c;
  if (!spec_.at(key).is_string()) fail(key, "one of " + list);
  const std::string value = spec_.at(key).get<std::string>();
  for (const auto& c : choices) {
    if (c == value) return value;
  }
  fail(key, "one of " + list);
}

std::vector<double> SpecKeys::numbers(const std::string& key, int count) {
  read_.insert(key);
  const std::string expected = count < 0 ? "a non-empty array of numbers"
                                         : "an array of " + std::to_string(count) + " numbers";
  if (!has(key) || !spec_.at(key).is_array()) fail(key, expected);
  const auto& array = spec_.at(key);
  if (array.empty() || (count >= 0 && static_cast<int>(array.size()) != count)) {
    fail(key, expected);
  }
  std::vector<double> values;
  for (const auto& v : array) {
    if (!v.is_number() || !std::isfinite(v.get<double>())) fail(key, expected);
    values.push_back(v.get<double>());
  }
  return values;
}

std::vector<std::string> SpecKeys::strings(const std::string& key,
                                           const std::vector<std::string>& choices) {
  read_.insert(key);
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "\"" : ", \"") + c + "\"";
  const std::string expected = "a non-empty array of strings among " + list;
  if (!has(key) || !spec_.at(key).is_array() || spec_.at(key).empty()) fail(key, expected);
  std::vector<std::string> values;
  for (const auto& v : spec_.at(key)) {
    if (!v.is_string() ||
        std::find(choices.begin(), choices.end(), v.get<std::string>()) == choices.end()) {
      fail(key, expected);
    }
    values.push_back(v.get<std::string>());
  }
  return values;
}

nlohmann::json SpecKeys::object(const std::string& key) {
  read_.insert(key);
  if (!has(key)) return nlohmann::json::object();
  if (!spec_.at(key).is_object()) fail(key, "an object");
  return spec_.at(key);
}

void SpecKeys::reject_unknown() const {
  for (const auto& item : spec_.items()) {
    if (!read_.count(item.key())) {
      std::string known;
      for (const auto& k : read_) known += (known.empty() ? "" : ", ") + k;
      throw InputError(where_ + " key '" + item.key() + "': unknown key; expected one of " + known);
    }
  }
}

}  // namespace stiffid::validation
