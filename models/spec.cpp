#include "models/spec.hpp"

#include <cmath>
#include <map>
#include <optional>
#include <set>

#include "data/error.hpp"
#include "data/text_input.hpp"

namespace stiffid::models {

namespace {

using nlohmann::json;
constexpr double kDeg = M_PI / 180.0;

struct Unit {
  std::string suffix;  // "" for a dimensionless key without suffix
  double factor;       // multiplies the value into the internal unit
};
const std::vector<Unit> kSeconds = {{"s", 1.0}};
const std::vector<Unit> kAngle = {{"deg", kDeg}, {"rad", 1.0}};
const std::vector<Unit> kNone = {{"", 1.0}};

// One JSON object of the spec: reads keys by base name and unit suffix, remembers which keys were
// read, and rejects the others (unknown key, or a known quantity in a wrong unit).
class Object {
 public:
  Object(const json& value, std::string path, const std::string& source)
      : value_(value), path_(std::move(path)), source_(source) {
    if (!value_.is_object()) fail(path_.empty() ? "spec" : path_, "expected a JSON object");
  }

  std::string key_path(const std::string& key) const {
    return path_.empty() ? key : path_ + "." + key;
  }
  [[noreturn]] void fail(const std::string& key_path, const std::string& what) const {
    throw InputError(source_ + ": " + key_path + ": " + what);
  }

  // The value of base_suffix for one of `units`, with the unit's factor; nullopt when absent.
  std::optional<std::pair<const json*, double>> find(const std::string& base,
                                                     const std::vector<Unit>& units,
                                                     std::string* found_key = nullptr) {
    known_.push_back({base, units});
    std::optional<std::pair<const json*, double>> out;
    for (const Unit& u : units) {
      const std::string key = u.suffix.empty() ? base : base + "_" + u.suffix;
      const auto it = value_.find(key);
      if (it == value_.end()) continue;
      if (out) fail(key_path(key), "given twice (in two units)");
      used_.insert(key);
      out = std::make_pair(&*it, u.factor);
      if (found_key) *found_key = key;
    }
    return out;
  }

  std::optional<double> number(const std::string& base, const std::vector<Unit>& units) {
    std::string key;
    const auto v = find(base, units, &key);
    if (!v) return std::nullopt;
    if (!v->first->is_number()) fail(key_path(key), "expected a number");
    const double x = v->first->get<double>() * v->second;
    if (!std::isfinite(x) && key != "snr_db") fail(key_path(key), "expected a finite number");
    return x;
  }
  void number(const std::string& base, const std::vector<Unit>& units, double& target) {
    if (auto v = number(base, units)) target = *v;
  }
  std::optional<std::string> text(const std::string& key) {
    const auto v = find(key, kNone);
    if (!v) return std::nullopt;
    if (!v->first->is_string()) fail(key_path(key), "expected a string");
    return v->first->get<std::string>();
  }
  std::optional<bool> boolean(const std::string& key) {
    const auto v = find(key, kNone);
    if (!v) return std::nullopt;
    if (!v->first->is_boolean()) fail(key_path(key), "expected true or false");
    return v->first->get<bool>();
  }
  std::optional<long long> integer(const std::string& key, long long lo, long long hi) {
    const auto v = find(key, kNone);
    if (!v) return std::nullopt;
    if (!v->first->is_number_integer() && !v->first->is_number_unsigned()) {
      fail(key_path(key), "expected an integer");
    }
    const long long x = v->first->is_number_unsigned()
                            ? static_cast<long long>(v->first->get<unsigned long long>())
                            : v->first->get<long long>();
    if (x < lo || x > hi) {
      fail(key_path(key), "expected an integer in [" + std::to_string(lo) + ", " +
                              std::to_string(hi) + "], got " + std::to_string(x));
    }
    return x;
  }
  std::optional<Eigen::VectorXd> vector(const std::string& base, const std::vector<Unit>& units,
                                        int size) {
    std::string key;
    const auto v = find(base, units, &key);
    if (!v) return std::nullopt;
    return to_vector(*v->first, key_path(key), size, v->second);
  }
  std::optional<Eigen::MatrixXd> matrix(const std::string& base, const std::vector<Unit>& units,
                                        int size) {
    std::string key;
    const auto v = find(base, units, &key);
    if (!v) return std::nullopt;
    return to_matrix(*v->first, key_path(key), size, v->second);
  }
  // An array of square matrices (a matrix table), each (size x size); nullopt when absent.
  std::optional<std::vector<Eigen::MatrixXd>> matrices(const std::string& base,
                                                       const std::vector<Unit>& units, int size) {
    std::string key;
    const auto v = find(base, units, &key);
    if (!v) return std::nullopt;
    const std::string where = key_path(key);
    if (!v->first->is_array() || v->first->empty()) {
      fail(where, "expected an array of " + std::to_string(size) + " x " + std::to_string(size) +
                      " matrices (one per time)");
    }
    std::vector<Eigen::MatrixXd> out;
    for (std::size_t k = 0; k < v->first->size(); ++k) {
      out.push_back(
          to_matrix((*v->first)[k], where + "[" + std::to_string(k) + "]", size, v->second));
    }
    return out;
  }
  std::optional<const json*> child(const std::string& key) {
    const auto v = find(key, kNone);
    if (!v) return std::nullopt;
    return v->first;
  }

  // Rejects every key that was not read.
  void finish() const {
    for (auto it = value_.begin(); it != value_.end(); ++it) {
      const std::string& key = it.key();
      if (used_.count(key)) continue;
      // A known quantity with another unit suffix? (longest matching base wins)
      const Known* best = nullptr;
      for (const Known& k : known_) {
        if (key.rfind(k.base + "_", 0) == 0 && (!best || k.base.size() > best->base.size())) {
          best = &k;
        }
      }
      if (best && !(best->units.size() == 1 && best->units[0].suffix.empty())) {
        std::string expected;
        for (const Unit& u : best->units) {
          expected += (expected.empty() ? "" : " or ") + best->base + "_" + u.suffix;
        }
        fail(key_path(key), "wrong or unknown unit, expected " + expected);
      }
      std::string expected;
      std::set<std::string> names;
      for (const Known& k : known_) {
        names.insert(k.units[0].suffix.empty() ? k.base : k.base + "_" + k.units[0].suffix);
      }
      for (const std::string& n : names) expected += (expected.empty() ? "" : ", ") + n;
      fail(key_path(key), "unknown key (expected one of: " + expected + ")");
    }
  }

  // A square matrix as an array of rows (size < 0: as many rows as given; a number for size 1).
  Eigen::MatrixXd to_matrix(const json& m, const std::string& where, int size,
                            double factor) const {
    if (m.is_number() && size == 1) {
      const double x = m.get<double>() * factor;
      if (!std::isfinite(x)) fail(where, "expected a finite number");
      return Eigen::MatrixXd::Constant(1, 1, x);
    }
    if (!m.is_array() || m.empty()) fail(where, "expected a square matrix as an array of rows");
    const int n = size > 0 ? size : static_cast<int>(m.size());
    if (static_cast<int>(m.size()) != n) {
      fail(where, "expected " + std::to_string(n) + " rows, got " + std::to_string(m.size()));
    }
    Eigen::MatrixXd out(n, n);
    for (int i = 0; i < n; ++i) {
      out.row(i) = to_vector(m[i], where + "[" + std::to_string(i) + "]", n, factor).transpose();
    }
    return out;
  }

  Eigen::VectorXd to_vector(const json& a, const std::string& where, int size,
                            double factor) const {
    if (!a.is_array()) fail(where, "expected an array of " + std::to_string(size) + " numbers");
    if (size >= 0 && static_cast<int>(a.size()) != size) {
      fail(where, "expected " + std::to_string(size) + " numbers, got " + std::to_string(a.size()));
    }
    Eigen::VectorXd out(static_cast<Eigen::Index>(a.size()));
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (!a[i].is_number()) fail(where + "[" + std::to_string(i) + "]", "expected a number");
      out(static_cast<Eigen::Index>(i)) = a[i].get<double>() * factor;
      if (!std::isfinite(out(static_cast<Eigen::Index>(i)))) {
        fail(where + "[" + std::to_string(i) + "]", "expected a finite number");
      }
    }
    return out;
  }

  const std::string& path() const { return path_; }
  const std::string& source() const { return source_; }

 private:
  struct Known {
    std::string base;
    std::vector<Unit> units;
  };
  const json& value_;
  std::string path_;
  const std::string& source_;
  std::set<std::string> used_;
  std::vector<Known> known_;
};

template <class F>
void rethrow_with_source(const std::string& source, F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    const std::string what = e.what();
    if (what.rfind(source + ":", 0) == 0) throw;
    throw InputError(source + ": " + what);
  }
}

TimeProfile parse_profile(const json& value, const std::string& path, const std::string& source,
                          double duration_s) {
  TimeProfile p;
  p.horizon_s = duration_s;
  if (value.is_string()) {
    rethrow_with_source(source,
                        [&] { p.kind = profile_kind_from_name(value.get<std::string>(), path); });
    if (p.kind == ProfileKind::table) {
      throw InputError(source + ": " + path +
                       ": a table profile needs an object with time_s and value");
    }
    return p;
  }
  Object o(value, path, source);
  const auto kind = o.text("kind");
  if (!kind) o.fail(o.key_path("kind"), "missing (constant, sigmoid, sinlin, sharp or table)");
  rethrow_with_source(source, [&] { p.kind = profile_kind_from_name(*kind, o.key_path("kind")); });
  o.number("start", kSeconds, p.start_s);
  o.number("horizon", kSeconds, p.horizon_s);
  if (p.kind == ProfileKind::table) {
    const auto t = o.vector("time", kSeconds, -1);
    const auto v = o.vector("value", kNone, -1);
    if (!t || !v) o.fail(path, "a table profile needs time_s and value arrays");
    p.table_time_s.assign(t->data(), t->data() + t->size());
    p.table_value.assign(v->data(), v->data() + v->size());
  }
  o.finish();
  rethrow_with_source(source, [&] { p.validate(path); });
  return p;
}

// Reads the element fields of `o` (kind, matrices, profiles, rotation) in `space` units.
void parse_element(Object& o, Viscoelasticity& e, Space space, int n, double duration_s) {
  if (const auto kind = o.text("kind")) {
    rethrow_with_source(o.source(),
                        [&] { e.kind = element_kind_from_name(*kind, o.key_path("kind")); });
  }
  auto matrix_field = [&](const std::string& field, Eigen::MatrixXd& target) {
    const std::string key = element_key(field, space);
    const std::size_t cut = key.find('_', field.size());
    const std::string suffix = key.substr(cut + 1);
    if (auto m = o.matrix(field, {{suffix, 1.0}}, n)) {
      target = *m;
      return true;
    }
    return false;
  };
  const bool stiffness_given = matrix_field("stiffness", e.stiffness);
  const bool damping_given = matrix_field("damping", e.damping);
  matrix_field("series_stiffness", e.series_stiffness);
  matrix_field("cubic_stiffness", e.cubic_stiffness);
  if (e.kind == ElementKind::poynting_thomson && e.series_stiffness.size() == 0) {
    o.fail(o.key_path(element_key("series_stiffness", space)), "missing (Poynting-Thomson)");
  }
  if (e.kind == ElementKind::duffing && e.cubic_stiffness.size() == 0) {
    o.fail(o.key_path(element_key("cubic_stiffness", space)), "missing (Duffing)");
  }
  e.stiffness_profile.horizon_s = duration_s;
  e.damping_profile.horizon_s = duration_s;
  const auto k_profile = o.child("stiffness_profile");
  const auto c_profile = o.child("damping_profile");
  if (k_profile) {
    e.stiffness_profile =
        parse_profile(**k_profile, o.key_path("stiffness_profile"), o.source(), duration_s);
  }
  if (c_profile) {
    e.damping_profile =
        parse_profile(**c_profile, o.key_path("damping_profile"), o.source(), duration_s);
  }
  // A matrix table replaces the constant matrix and its profile: {"time_s": [P], KEY: [P][n][n]}.
  auto table_field = [&](const std::string& field, bool matrix_given, bool profile_given,
                         Eigen::MatrixXd& matrix, MatrixTable& table) {
    const std::string table_key = field + "_table";
    const auto t = o.child(table_key);
    if (!t) return;
    const std::string path = o.key_path(table_key);
    const std::string value_key = element_key(field, space);
    if (matrix_given) o.fail(path, "give either " + table_key + " or " + value_key + ", not both");
    if (profile_given) {
      o.fail(path, "a table replaces " + field + "_profile (the table holds the matrices), " +
                       "give only one");
    }
    Object table_object(**t, path, o.source());
    const auto times = table_object.vector("time", kSeconds, -1);
    const std::size_t cut = value_key.find('_', field.size());
    const auto values = table_object.matrices(field, {{value_key.substr(cut + 1), 1.0}}, n);
    table_object.finish();
    if (!times) table_object.fail(table_object.key_path("time_s"), "missing");
    if (!values) table_object.fail(table_object.key_path(value_key), "missing");
    table.time_s.assign(times->data(), times->data() + times->size());
    table.value = *values;
    matrix.resize(0, 0);
  };
  table_field("stiffness", stiffness_given, k_profile.has_value(), e.stiffness, e.stiffness_table);
  table_field("damping", damping_given, c_profile.has_value(), e.damping, e.damping_table);
  o.number("damping_rotation", kAngle, e.damping_rotation_rad);
}

// The direction of a pulse or ramp: direction_deg|rad, octant (0..7) or "random_octant".
void parse_direction(Object& o, double& direction_rad, bool& random_octant) {
  int given = 0;
  if (auto d = o.number("direction", kAngle)) {
    direction_rad = *d;
    ++given;
  }
  if (auto k = o.integer("octant", 0, 7)) {
    direction_rad = octant_direction_rad(static_cast<int>(*k));
    ++given;
  }
  if (auto r = o.boolean("random_octant")) {
    random_octant = *r;
    if (*r) ++given;
  }
  if (given > 1) {
    o.fail(o.path(), "give one of direction_deg (or _rad), octant, random_octant");
  }
}

void parse_perturbation(const json& value, const std::string& path, const std::string& source,
                        ModelKind model, TrialSpec& spec) {
  Object o(value, path, source);
  const auto kind = o.text("kind");
  if (!kind) o.fail(o.key_path("kind"), "missing (impulse, pulse, ramp_and_hold or random_force)");
  if (*kind == "impulse" || *kind == "pulse") {
    ForcePulse p = *kind == "impulse" ? force_impulse(2.5, 0.0) : force_pulse(2.5, 0.0);
    o.number("onset", kSeconds, p.onset_s);
    o.number("duration", kSeconds, p.duration_s);
    o.number("amplitude", {{"n", 1.0}}, p.amplitude_n);
    parse_direction(o, p.direction_rad, p.random_octant);
    o.finish();
    if (!(p.duration_s > 0.0)) o.fail(o.key_path("duration_s"), "expected a positive duration");
    if (!(p.onset_s >= 0.0)) o.fail(o.key_path("onset_s"), "expected a non-negative onset");
    spec.perturbations.pulses.push_back(p);
  } else if (*kind == "ramp_and_hold") {
    DisplacementRamp r;
    o.number("onset", kSeconds, r.onset_s);
    o.number("amplitude", {{"m", 1.0}, {"mm", 1e-3}}, r.amplitude_m);
    o.number("ramp", kSeconds, r.ramp_s);
    o.number("plateau", kSeconds, r.plateau_s);
    o.number("return", kSeconds, r.return_s);
    o.number("servo_stiffness", {{"n_per_m", 1.0}}, r.servo_stiffness_n_per_m);
    o.number("servo_damping", {{"ns_per_m", 1.0}}, r.servo_damping_ns_per_m);
    parse_direction(o, r.direction_rad, r.random_octant);
    o.finish();
    if (!(r.onset_s >= 0.0)) o.fail(o.key_path("onset_s"), "expected a non-negative onset");
    if (!(r.ramp_s > 0.0)) o.fail(o.key_path("ramp_s"), "expected a positive duration");
    if (!(r.plateau_s >= 0.0)) o.fail(o.key_path("plateau_s"), "expected a non-negative duration");
    if (!(r.return_s > 0.0)) o.fail(o.key_path("return_s"), "expected a positive duration");
    if (!(r.servo_stiffness_n_per_m > 0.0)) {
      o.fail(o.key_path("servo_stiffness_n_per_m"), "expected a positive stiffness");
    }
    if (!(r.servo_damping_ns_per_m >= 0.0)) {
      o.fail(o.key_path("servo_damping_ns_per_m"), "expected a non-negative damping");
    }
    spec.perturbations.ramps.push_back(r);
  } else if (*kind == "random_force") {
    if (spec.perturbations.random) o.fail(o.key_path("kind"), "only one random_force per trial");
    RandomForce& f = spec.perturbations.random_force;
    o.number("bandwidth", {{"hz", 1.0}}, f.bandwidth_hz);
    if (auto order = o.integer("filter_order", 1, 20)) f.filter_order = static_cast<int>(*order);
    if (auto factor = o.integer("oversample", 1, 64)) f.oversample = static_cast<int>(*factor);
    o.number("coupling", {{"percent", 1.0}}, f.coupling_percent);
    o.number("peak_to_peak", {{"n", 1.0}}, f.peak_to_peak_n);
    o.number("rms", {{"n", 1.0}}, f.rms_n);
    o.number("warmup", kSeconds, f.warmup_s);
    if (auto hold = o.text("hold")) {
      if (*hold == "first_order") {
        f.hold = InputHold::first_order;
      } else if (*hold == "zero_order") {
        f.hold = InputHold::zero_order;
      } else {
        o.fail(o.key_path("hold"), "expected first_order or zero_order, got \"" + *hold + "\"");
      }
    }
    o.finish();
    if (!(f.coupling_percent >= 0.0 && f.coupling_percent <= 100.0)) {
      o.fail(o.key_path("coupling_percent"), "expected a percentage in [0, 100]");
    }
    if (!(f.bandwidth_hz > 0.0))
      o.fail(o.key_path("bandwidth_hz"), "expected a positive frequency");
    if (!(f.peak_to_peak_n >= 0.0)) o.fail(o.key_path("peak_to_peak_n"), "expected >= 0");
    if (!(f.rms_n >= 0.0)) o.fail(o.key_path("rms_n"), "expected >= 0");
    if (!(f.warmup_s >= 0.0)) o.fail(o.key_path("warmup_s"), "expected >= 0");
    spec.perturbations.random = true;
  } else {
    o.fail(o.key_path("kind"), "unknown perturbation \"" + *kind +
                                   "\", expected impulse, pulse, ramp_and_hold or random_force");
  }
  (void)model;
}

}  // namespace

TrialSpec parse_trial_spec(const json& value, const std::string& source) {
  TrialSpec spec;
  spec.source = source;
  Object root(value, "", source);
  if (const auto model = root.text("model")) {
    if (*model == "arm") {
      spec.model = ModelKind::arm;
    } else if (*model == "endpoint") {
      spec.model = ModelKind::endpoint;
    } else {
      root.fail("model", "unknown model \"" + *model + "\", expected arm or endpoint");
    }
  } else {
    root.fail("model", "missing (arm or endpoint)");
  }
  root.number("duration", kSeconds, spec.duration_s);
  root.number("sample_rate", {{"hz", 1.0}}, spec.sample_rate_hz);
  if (!(spec.duration_s > 0.0)) root.fail("duration_s", "expected a positive duration");
  if (!(spec.sample_rate_hz > 0.0)) root.fail("sample_rate_hz", "expected a positive rate");
  if (auto seed = root.integer("seed", 0, std::numeric_limits<long long>::max())) {
    spec.seed = static_cast<std::uint64_t>(*seed);
  }
  const bool arm = spec.model == ModelKind::arm;
  const Space space = arm ? Space::joint : Space::endpoint;
  int n = 2;

  if (arm) {
    if (const auto a = root.child("arm")) {
      Object o(**a, "arm", source);
      o.number("l1", {{"m", 1.0}}, spec.arm.l1_m);
      o.number("r1", {{"m", 1.0}}, spec.arm.r1_m);
      o.number("m1", {{"kg", 1.0}}, spec.arm.m1_kg);
      o.number("iz1", {{"kg_m2", 1.0}}, spec.arm.iz1_kg_m2);
      o.number("l2", {{"m", 1.0}}, spec.arm.l2_m);
      o.number("r2", {{"m", 1.0}}, spec.arm.r2_m);
      o.number("m2", {{"kg", 1.0}}, spec.arm.m2_kg);
      o.number("iz2", {{"kg_m2", 1.0}}, spec.arm.iz2_kg_m2);
      o.finish();
      rethrow_with_source(source, [&] { spec.arm.validate(); });
    }
    if (const auto t = root.child("task")) {
      Object o(**t, "task", source);
      const auto kind = o.text("kind");
      if (!kind || (*kind != "posture" && *kind != "reach")) {
        o.fail("task.kind", "expected posture or reach");
      }
      if (*kind == "posture") {
        spec.task.kind = TaskKind::posture;
        const auto hand = o.vector("hand", {{"m", 1.0}}, 2);
        const auto angles = o.vector("joint_angles", kAngle, 2);
        if (hand && angles) o.fail("task", "give hand_m or joint_angles_deg, not both");
        if (hand) spec.task.posture_hand_m = *hand;
        if (angles) {
          spec.task.posture_by_angles = true;
          spec.task.posture_joint_rad = *angles;
        }
      } else {
        spec.task.kind = TaskKind::reach;
        if (auto v = o.vector("start", {{"m", 1.0}}, 2)) spec.task.reach_start_m = *v;
        if (auto v = o.vector("target", {{"m", 1.0}}, 2)) spec.task.reach_target_m = *v;
        o.number("rate", {{"per_s", 1.0}}, spec.task.reach_rate_per_s);
        o.number("q", kNone, spec.task.reach_q);
        o.number("midpoint", kSeconds, spec.task.reach_midpoint_s);
      }
      o.finish();
    }
    spec.joint.stiffness_profile.horizon_s = spec.duration_s;
    spec.joint.damping_profile.horizon_s = spec.duration_s;
    if (const auto v = root.child("viscoelasticity")) {
      Object o(**v, "viscoelasticity", source);
      parse_element(o, spec.joint, space, 2, spec.duration_s);
      o.finish();
    }
  } else {
    if (const auto v = root.child("endpoint")) {
      Object o(**v, "endpoint", source);
      if (auto i = o.matrix("inertia", {{"kg", 1.0}}, -1)) spec.endpoint.inertia_kg = *i;
      n = static_cast<int>(spec.endpoint.inertia_kg.rows());
      parse_element(o, spec.endpoint.element, space, n, spec.duration_s);
      o.finish();
    }
  }
  if (const auto init = root.child("initial")) {
    Object o(**init, "initial", source);
    const std::vector<Unit> position = arm ? kAngle : std::vector<Unit>{{"m", 1.0}};
    const std::vector<Unit> rate = arm ? std::vector<Unit>{{"deg_per_s", kDeg}, {"rad_per_s", 1.0}}
                                       : std::vector<Unit>{{"m_per_s", 1.0}};
    if (auto d = o.vector("deviation", position, n)) spec.initial_deviation = *d;
    if (auto r = o.vector("rate", rate, n)) spec.initial_deviation_rate = *r;
    o.finish();
  }
  if (const auto p = root.child("perturbations")) {
    if (!(*p)->is_array()) root.fail("perturbations", "expected an array of perturbation objects");
    for (std::size_t k = 0; k < (*p)->size(); ++k) {
      parse_perturbation((**p)[k], "perturbations[" + std::to_string(k) + "]", source, spec.model,
                         spec);
    }
  }
  if (const auto noise = root.child("noise")) {
    Object o(**noise, "noise", source);
    if (const auto snr = o.find("snr", {{"db", 1.0}})) {
      const json& s = *snr->first;
      if (s.is_string() && (s.get<std::string>() == "inf" || s.get<std::string>() == "infinity")) {
        spec.noise.snr_db = std::numeric_limits<double>::infinity();
      } else if (s.is_number()) {
        spec.noise.snr_db = s.get<double>();
      } else if (!s.is_null()) {
        o.fail("noise.snr_db", "expected a number in dB, \"inf\" or null (no noise)");
      }
    }
    if (auto sdn = o.boolean("signal_dependent")) spec.noise.signal_dependent = *sdn;
    o.number("sdn_max_snr", {{"db", 1.0}}, spec.noise.sdn_max_snr_db);
    o.finish();
  }
  if (const auto integ = root.child("integrator")) {
    Object o(**integ, "integrator", source);
    if (auto method = o.text("method")) {
      rethrow_with_source(source, [&] {
        spec.integrator.kind = integrator_kind_from_name(*method, "integrator.method");
      });
    }
    o.number("absolute_tolerance", {{arm ? "rad" : "m", 1.0}}, spec.integrator.absolute_tolerance);
    o.number("relative_tolerance", kNone, spec.integrator.relative_tolerance);
    o.number("initial_step", kSeconds, spec.integrator.initial_step_s);
    if (auto m = o.integer("max_steps", 1, std::numeric_limits<long>::max())) {
      spec.integrator.max_steps = static_cast<long>(*m);
    }
    o.finish();
  }
  root.finish();
  spec.validate();
  return spec;
}

TrialSpec read_trial_spec(const std::string& path) {
  return parse_trial_spec(data::read_json_file(path), path);
}

namespace {

json matrix_json(const Eigen::MatrixXd& m) {
  json rows = json::array();
  for (Eigen::Index i = 0; i < m.rows(); ++i) {
    json row = json::array();
    for (Eigen::Index j = 0; j < m.cols(); ++j) row.push_back(m(i, j));
    rows.push_back(row);
  }
  return rows;
}

json vector_json(const Eigen::VectorXd& v) {
  json out = json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(v(i));
  return out;
}

json profile_json(const TimeProfile& p) {
  json out = {{"kind", profile_kind_name(p.kind)}};
  if (p.kind == ProfileKind::table) {
    out["time_s"] = p.table_time_s;
    out["value"] = p.table_value;
  } else {
    out["start_s"] = p.start_s;
    out["horizon_s"] = p.horizon_s;
  }
  return out;
}

json table_json(const MatrixTable& table, const std::string& value_key) {
  json values = json::array();
  for (const Eigen::MatrixXd& m : table.value) values.push_back(matrix_json(m));
  return {{"time_s", table.time_s}, {value_key, values}};
}

void element_json(const Viscoelasticity& e, Space space, json& out) {
  out["kind"] = element_kind_name(e.kind);
  if (e.stiffness_table.empty()) {
    out[element_key("stiffness", space)] = matrix_json(e.stiffness);
    out["stiffness_profile"] = profile_json(e.stiffness_profile);
  } else {
    out["stiffness_table"] = table_json(e.stiffness_table, element_key("stiffness", space));
  }
  if (e.damping_table.empty()) {
    out[element_key("damping", space)] = matrix_json(e.damping);
    out["damping_profile"] = profile_json(e.damping_profile);
    out["damping_rotation_rad"] = e.damping_rotation_rad;
  } else {
    out["damping_table"] = table_json(e.damping_table, element_key("damping", space));
  }
  if (e.series_stiffness.size())
    out[element_key("series_stiffness", space)] = matrix_json(e.series_stiffness);
  if (e.cubic_stiffness.size()) {
    out[element_key("cubic_stiffness", space)] = matrix_json(e.cubic_stiffness);
  }
}

}  // namespace

json trial_spec_to_json(const TrialSpec& spec) {
  const bool arm = spec.model == ModelKind::arm;
  json out;
  out["model"] = arm ? "arm" : "endpoint";
  out["duration_s"] = spec.duration_s;
  out["sample_rate_hz"] = spec.sample_rate_hz;
  out["seed"] = spec.seed;
  if (arm) {
    const ArmParameters& a = spec.arm;
    out["arm"] = {{"l1_m", a.l1_m},           {"r1_m", a.r1_m},          {"m1_kg", a.m1_kg},
                  {"iz1_kg_m2", a.iz1_kg_m2}, {"l2_m", a.l2_m},          {"r2_m", a.r2_m},
                  {"m2_kg", a.m2_kg},         {"iz2_kg_m2", a.iz2_kg_m2}};
    json task;
    if (spec.task.kind == TaskKind::posture) {
      task["kind"] = "posture";
      if (spec.task.posture_by_angles) {
        task["joint_angles_rad"] = vector_json(spec.task.posture_joint_rad);
      } else {
        task["hand_m"] = vector_json(spec.task.posture_hand_m);
      }
    } else {
      task["kind"] = "reach";
      task["start_m"] = vector_json(spec.task.reach_start_m);
      task["target_m"] = vector_json(spec.task.reach_target_m);
      task["rate_per_s"] = spec.task.reach_rate_per_s;
      task["q"] = spec.task.reach_q;
      if (!std::isnan(spec.task.reach_midpoint_s)) task["midpoint_s"] = spec.task.reach_midpoint_s;
    }
    out["task"] = task;
    json visco;
    element_json(spec.joint, Space::joint, visco);
    out["viscoelasticity"] = visco;
  } else {
    json endpoint;
    endpoint["inertia_kg"] = matrix_json(spec.endpoint.inertia_kg);
    element_json(spec.endpoint.element, Space::endpoint, endpoint);
    out["endpoint"] = endpoint;
  }
  if (spec.initial_deviation.size() || spec.initial_deviation_rate.size()) {
    json init;
    if (spec.initial_deviation.size()) {
      init[arm ? "deviation_rad" : "deviation_m"] = vector_json(spec.initial_deviation);
    }
    if (spec.initial_deviation_rate.size()) {
      init[arm ? "rate_rad_per_s" : "rate_m_per_s"] = vector_json(spec.initial_deviation_rate);
    }
    out["initial"] = init;
  }
  json perturbations = json::array();
  for (const ForcePulse& p : spec.perturbations.pulses) {
    json j = {{"kind", "pulse"},
              {"onset_s", p.onset_s},
              {"duration_s", p.duration_s},
              {"amplitude_n", p.amplitude_n}};
    if (p.random_octant) {
      j["random_octant"] = true;
    } else {
      j["direction_rad"] = p.direction_rad;
    }
    perturbations.push_back(j);
  }
  for (const DisplacementRamp& r : spec.perturbations.ramps) {
    json j = {{"kind", "ramp_and_hold"},
              {"onset_s", r.onset_s},
              {"amplitude_m", r.amplitude_m},
              {"ramp_s", r.ramp_s},
              {"plateau_s", r.plateau_s},
              {"return_s", r.return_s},
              {"servo_stiffness_n_per_m", r.servo_stiffness_n_per_m},
              {"servo_damping_ns_per_m", r.servo_damping_ns_per_m}};
    if (r.random_octant) {
      j["random_octant"] = true;
    } else {
      j["direction_rad"] = r.direction_rad;
    }
    perturbations.push_back(j);
  }
  if (spec.perturbations.random) {
    const RandomForce& f = spec.perturbations.random_force;
    perturbations.push_back(
        {{"kind", "random_force"},
         {"bandwidth_hz", f.bandwidth_hz},
         {"filter_order", f.filter_order},
         {"oversample", f.oversample},
         {"coupling_percent", f.coupling_percent},
         {"peak_to_peak_n", f.peak_to_peak_n},
         {"rms_n", f.rms_n},
         {"warmup_s", f.warmup_s},
         {"hold", f.hold == InputHold::first_order ? "first_order" : "zero_order"}});
  }
  out["perturbations"] = perturbations;
  json noise;
  noise["snr_db"] = std::isfinite(spec.noise.snr_db) ? json(spec.noise.snr_db) : json(nullptr);
  noise["signal_dependent"] = spec.noise.signal_dependent;
  noise["sdn_max_snr_db"] = spec.noise.sdn_max_snr_db;
  out["noise"] = noise;
  out["integrator"] = {
      {"method", integrator_kind_name(spec.integrator.kind)},
      {arm ? "absolute_tolerance_rad" : "absolute_tolerance_m", spec.integrator.absolute_tolerance},
      {"relative_tolerance", spec.integrator.relative_tolerance},
      {"initial_step_s", spec.integrator.initial_step_s},
      {"max_steps", spec.integrator.max_steps}};
  return out;
}

}  // namespace stiffid::models
