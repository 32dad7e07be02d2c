#pragma once
// Reading a cell evaluator's trial spec (a JSON object) with errors that name the key: every key
// read is checked for type and range, and keys nobody read are rejected, so a typo in a study file
// is an InputError and not a silently ignored setting.

#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

namespace stiffid::validation {

class SpecKeys {
 public:
  /// `spec` must be a JSON object; `where` prefixes messages (e.g. "evaluator 'synthetic'").
  SpecKeys(const nlohmann::json& spec, std::string where);

  bool has(const std::string& key) const;
  /// A finite number in [low, high]; `fallback` when absent.
  double number(const std::string& key, double fallback, double low, double high);
  /// A required finite number in [low, high].
  double number(const std::string& key, double low, double high);
  /// An integer in [low, high]; `fallback` when absent.
  long integer(const std::string& key, long fallback, long low, long high);
  bool boolean(const std::string& key, bool fallback);
  /// One of `choices`; `fallback` when absent.
  std::string choice(const std::string& key, const std::string& fallback,
                     const std::vector<std::string>& choices);
  /// An array of exactly `count` finite numbers (count < 0: any non-empty length).
  std::vector<double> numbers(const std::string& key, int count);
  /// A non-empty array of strings, each one of `choices`.
  std::vector<std::string> strings(const std::string& key, const std::vector<std::string>& choices);
  /// A sub-object (empty object when absent), marked as read; read it with its own SpecKeys.
  nlohmann::json object(const std::string& key);
  /// Throws InputError naming the first key that was never read.
  void reject_unknown() const;
  /// Prefix for messages about a sub-object.
  std::string path(const std::string& key) const { return where_ + " key '" + key + "'"; }

 private:
  [[noreturn]] void fail(const std::string& key, const std::string& expected) const;
  const nlohmann::json& spec_;
  std::string where_;
  std::set<std::string> read_;
};

}  // namespace stiffid::validation
