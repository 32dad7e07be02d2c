// JSON trial specs (models/spec.hpp): errors name the key path; the shipped examples parse.

#include <boost/test/unit_test.hpp>
#include <filesystem>
#include <string>

#include "data/error.hpp"
#include "models/spec.hpp"
#include "tests/support/support.hpp"

namespace m = stiffid::models;
using nlohmann::json;

namespace {

json posture() {
  return json::parse(R"({"model": "arm", "duration_s": 1, "sample_rate_hz": 100,
    "task": {"kind": "posture", "hand_m": [0.4, 0.0]},
    "viscoelasticity": {"kind": "kelvin_voigt", "stiffness_nm_per_rad": [[35, 5], [5, 20]],
                        "damping_nms_per_rad": [[0.35, 0.05], [0.05, 0.2]]},
    "perturbations": [{"kind": "impulse", "onset_s": 0.5, "direction_deg": 90}]})");
}

using stiffid::test::mentions;

// The error message of parsing `spec`, or "" when it parses.
std::string error_of(const json& spec) {
  return stiffid::test::input_error_message([&] { m::parse_trial_spec(spec, "spec.json"); });
}

}  // namespace

BOOST_AUTO_TEST_CASE(a_valid_spec_parses_with_units_converted) {
  const m::TrialSpec spec = m::parse_trial_spec(posture(), "spec.json");
  BOOST_CHECK_CLOSE(spec.perturbations.pulses.at(0).direction_rad, M_PI / 2, 1e-12);
  BOOST_CHECK_EQUAL(spec.joint.stiffness(0, 1), 5.0);
  // Round trip through trial_spec_to_json.
  const m::TrialSpec again = m::parse_trial_spec(m::trial_spec_to_json(spec), "again.json");
  BOOST_CHECK_EQUAL(again.perturbations.pulses.at(0).direction_rad,
                    spec.perturbations.pulses[0].direction_rad);
  BOOST_CHECK(again.joint.damping == spec.joint.damping);
}

BOOST_AUTO_TEST_CASE(unknown_key_is_named) {
  json s = posture();
  s["task"]["speed"] = 3;
  const std::string e = error_of(s);
  BOOST_CHECK(mentions(e, "spec.json: task.speed: unknown key"));
}

BOOST_AUTO_TEST_CASE(wrong_unit_is_named) {
  json s = posture();
  s["viscoelasticity"].erase("stiffness_nm_per_rad");
  s["viscoelasticity"]["stiffness_n_per_m"] =
      json::array({json::array({35, 5}), json::array({5, 20})});
  BOOST_CHECK(mentions(
      error_of(s),
      "viscoelasticity.stiffness_n_per_m: wrong or unknown unit, expected stiffness_nm_per_rad"));
  json t = posture();
  t["duration_ms"] = 1000;
  BOOST_CHECK(mentions(error_of(t), "duration_ms: wrong or unknown unit, expected duration_s"));
}

BOOST_AUTO_TEST_CASE(impossible_values_are_named) {
  json mass = posture();
  mass["arm"] = {{"m1_kg", -1.0}};
  BOOST_CHECK(mentions(error_of(mass), "arm.m1_kg"));
  json reach = posture();
  reach["task"]["hand_m"] = json::array({0.9, 0.0});
  BOOST_CHECK(mentions(error_of(reach), "task.hand_m"));
  BOOST_CHECK(mentions(error_of(reach), "out of reach"));
  json stiff = posture();
  stiff["viscoelasticity"]["stiffness_nm_per_rad"] =
      json::array({json::array({1, 5}), json::array({5, 1})});
  BOOST_CHECK(mentions(error_of(stiff),
                       "viscoelasticity.stiffness_nm_per_rad: expected a positive definite"));
  json inertia = json::parse(R"({"model": "endpoint", "duration_s": 1, "sample_rate_hz": 50,
    "endpoint": {"inertia_kg": [[1, 2], [2, 1]]}})");
  BOOST_CHECK(mentions(error_of(inertia), "endpoint.inertia_kg: expected a positive definite"));
  json onset = posture();
  onset["perturbations"][0]["onset_s"] = -1;
  BOOST_CHECK(mentions(error_of(onset), "perturbations[0].onset_s"));
  json coupling = posture();
  coupling["perturbations"] = json::array({{{"kind", "random_force"}, {"coupling_percent", 150}}});
  BOOST_CHECK(mentions(error_of(coupling), "perturbations[0].coupling_percent"));
}

BOOST_AUTO_TEST_CASE(shipped_example_specs_parse) {
  int count = 0;
  for (const auto& entry :
       std::filesystem::directory_iterator(STIFFID_SOURCE_DIR "/models/specs")) {
    BOOST_CHECK_NO_THROW(m::read_trial_spec(entry.path().string()));
    ++count;
  }
  BOOST_CHECK_GE(count, 20);
}
