// `stiffid tfa` end to end: the JSON contract on a simulated posture trial (scipy fixture,
// tests/data/tfa/make_posture_trials.py) and exit code 2 with no output file on bad input.
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <utility>

#include "tests/support/support.hpp"

namespace fs = std::filesystem;

namespace {

const std::string kTrial = std::string(STIFFID_TEST_DATA_DIR) + "/tfa/posture_constant.csv";

int run(const std::string& args) {
  const int status =
      std::system((std::string(STIFFID_BINARY) + " tfa " + args + " 2>/dev/null").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Exit code of `stiffid tfa ARGS`, with what it printed on stderr in `err` (stdout discarded).
int run(const std::string& args, std::string& err) {
  const std::string command = std::string(STIFFID_BINARY) + " tfa " + args + " 2>&1 >/dev/null";
  err.clear();
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return -1;
  char buffer[512];
  while (std::fgets(buffer, sizeof buffer, pipe) != nullptr) err += buffer;
  const int status = ::pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// The JSON document in `path` (a missing file fails the test with the file's name).
nlohmann::json read_json(const fs::path& path) {
  BOOST_REQUIRE_MESSAGE(fs::exists(path), "cannot open " << path);
  return nlohmann::json::parse(stiffid::test::read_text(path));
}

// A fresh path `name` in this test program's temporary folder (removed when the program ends).
fs::path scratch(const std::string& name) {
  static const stiffid::test::TempFolder folder("tfa_cli");
  fs::remove(folder.path / name);
  return folder.path / name;
}

using LineEdit = std::function<std::string(const std::string&)>;

// A copy `name` of the fixture trial (header "t,th1[rad],th2[rad],fx[N],fy[N]") in the scratch
// folder: its header through `header`, every data row through `row`; a row that `row` turns into
// an empty string is dropped.
fs::path fixture_copy(
    const std::string& name, const LineEdit& row,
    const LineEdit& header = [](const std::string& line) { return line; }) {
  const fs::path path = scratch(name);
  std::ifstream in(kTrial);
  std::ofstream out(path);
  std::string line;
  std::getline(in, line);
  BOOST_REQUIRE_EQUAL(line, "t,th1[rad],th2[rad],fx[N],fy[N]");
  out << header(line) << '\n';
  while (std::getline(in, line)) {
    const std::string edited = row(line);
    if (!edited.empty()) out << edited << '\n';
  }
  return path;
}

// The fields of a fixture row: t, th1, th2, fx, fy.
std::array<double, 5> fields(const std::string& line) {
  std::array<double, 5> v{};
  std::istringstream in(line);
  char comma = 0;
  in >> v[0] >> comma >> v[1] >> comma >> v[2] >> comma >> v[3] >> comma >> v[4];
  return v;
}

}  // namespace

BOOST_AUTO_TEST_CASE(writes_the_documented_keys_with_auto_onset) {
  const fs::path out = scratch("out.json"), map = scratch("map.csv");
  BOOST_REQUIRE_EQUAL(run(kTrial + " --angles th1,th2 --onset auto --forces fx,fy -o " +
                          out.string() + " --method spectrogram --spectrogram " + map.string()),
                      0);
  const nlohmann::json j = read_json(out);
  for (const char* key : {"t_s", "f_hz", "amplitude", "alpha_per_s", "K_nm_per_rad",
                          "C_nms_per_rad", "eigenvectors", "normalized_force", "options"}) {
    BOOST_CHECK_MESSAGE(j.contains(key), key);
  }
  const size_t frames = j["t_s"].size();
  BOOST_CHECK_GT(frames, 900u);  // 2.5 ms hop over ~2.4 s of free response
  BOOST_CHECK_EQUAL(j["f_hz"].size(), 2u);
  BOOST_CHECK_EQUAL(j["amplitude"][1][0].size(), frames);
  BOOST_CHECK_EQUAL(j["K_nm_per_rad"][0][1].size(), frames);
  // The fixture holds 0.5 s before the onset: each mode's amplitude-to-noise ratio is reported.
  BOOST_REQUIRE_EQUAL(j["anr_db"].size(), 2u);
  BOOST_CHECK_EQUAL(j["anr_db"][1].size(), frames);
  BOOST_CHECK(j["anr_db"][1][frames / 2].is_number());
  BOOST_CHECK_CLOSE(j["onset_s"].get<double>(), 2.5, 1e-6);
  // Constant K0 = [35 5; 5 20] N m/rad (eq 52): mid-record k11 within 1 % (test_tfa_posture
  // measures 0.03 % RMS over 2.6-4.5 s).
  BOOST_CHECK_CLOSE(j["K_nm_per_rad"][0][0][frames / 2].get<double>(), 35.0, 1.0);
  BOOST_CHECK(fs::file_size(map) > 0);
}

BOOST_AUTO_TEST_CASE(chirped_frame_fits_are_the_default_of_the_spectrogram_method) {
  // The chirped frame fits are the default and recorded in "options"; --chirp false gives the
  // stationary frame model, with the same JSON shape and, on this constant-K fixture, the
  // mid-record k11 within 1 % of K0 either way; a value that is not a boolean is a usage error
  // (exit 2) and writes nothing.
  const fs::path stationary = scratch("stationary.json"), chirped = scratch("chirped.json");
  const std::string common = kTrial + " --angles th1,th2 --onset 2.5 --method spectrogram -o ";
  BOOST_REQUIRE_EQUAL(run(common + chirped.string()), 0);
  BOOST_REQUIRE_EQUAL(run(common + stationary.string() + " --chirp false"), 0);
  const nlohmann::json s = read_json(stationary), c = read_json(chirped);
  BOOST_CHECK(!s["options"]["chirp"].get<bool>());
  BOOST_CHECK(c["options"]["chirp"].get<bool>());
  BOOST_REQUIRE_EQUAL(c["t_s"].size(), s["t_s"].size());
  const size_t frames = c["t_s"].size();
  BOOST_CHECK_CLOSE(c["K_nm_per_rad"][0][0][frames / 2].get<double>(), 35.0, 1.0);
  BOOST_CHECK_CLOSE(s["K_nm_per_rad"][0][0][frames / 2].get<double>(), 35.0, 1.0);
  BOOST_CHECK(c["K_nm_per_rad"] != s["K_nm_per_rad"]);  // the option reaches the frame fits
  const fs::path none = scratch("none.json");
  BOOST_CHECK_EQUAL(run(common + none.string() + " --chirp maybe"), 2);
  BOOST_CHECK(!fs::exists(none));
}

BOOST_AUTO_TEST_CASE(the_default_method_is_modal_with_validity_and_anr_per_mode) {
  const fs::path out = scratch("modal.json");
  BOOST_REQUIRE_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --decimate-hz 200 --knots-s 0.1 -o " +
          out.string()),
      0);
  const nlohmann::json j = read_json(out);
  BOOST_CHECK_EQUAL(j["method"], "modal");
  for (const char* key : {"t_s",
                          "f_hz",
                          "amplitude",
                          "alpha_per_s",
                          "gamma_per_s",
                          "eta_squared_per_s2",
                          "K_nm_per_rad",
                          "C_nms_per_rad",
                          "eigenvectors",
                          "normalized_force",
                          "options",
                          "valid",
                          "anr_db",
                          "K_valid",
                          "noise_covariance_rad2",
                          "residual_rms_whitened",
                          "effective_parameters",
                          "bic",
                          "decay_tracks_residual_rms_whitened",
                          "decay_tracks_bic",
                          "iterations",
                          "decay_ratio",
                          "frequency_ratio",
                          "real_terms",
                          "offset_rad",
                          "track_roughness_local"}) {
    BOOST_CHECK_MESSAGE(j.contains(key), key);
  }
  for (const char* key :
       {"track_roughness", "decay_tie", "decay_tie_from_data", "frequency_tie",
        "frequency_tie_from_data", "shape_weight", "real_terms", "real_terms_from_data", "offsets",
        "shape_refit", "shape_phase_factor", "local_roughness_dof", "lost_track_time_s"}) {
    BOOST_CHECK_MESSAGE(j["options"].contains(key), key);
  }
  // The noise-free constant-K trial needs no rough tracks: the shape refit is not taken, and the
  // roughness is one for the whole record.
  BOOST_CHECK(!j["options"]["shape_refit"].get<bool>());
  BOOST_CHECK(j["track_roughness_local"].is_null());
  BOOST_CHECK_EQUAL(j["options"]["local_roughness_dof"].get<double>(), 1.0);
  BOOST_CHECK_EQUAL(j["options"]["lost_track_time_s"].get<double>(), 0.3);
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 2.5 --no-shape-refit -o " +
                        scratch("no_refit.json").string()),
                    0);
  // A negative nu of the local roughness is refused by name (exit 2), and nothing is written.
  const fs::path bad = scratch("bad_local.json");
  BOOST_CHECK_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --local-roughness-dof -1 -o " + bad.string()), 2);
  BOOST_CHECK(!fs::exists(bad));
  // So is a lost-track time constant that is not a number.
  BOOST_CHECK_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --lost-track-time-s nan -o " + bad.string()), 2);
  BOOST_CHECK(!fs::exists(bad));
  BOOST_CHECK(j["options"]["offsets"].get<bool>());
  BOOST_CHECK(j["options"]["second_order"].get<bool>());
  BOOST_CHECK(j["second_order_mode"].get<int>() >= 0);
  {
    // --no-second-order: the terms are not offered, and the JSON says so.
    const fs::path plain = scratch("no_second_order.json");
    BOOST_REQUIRE_EQUAL(
        run(kTrial + " --angles th1,th2 --onset 2.5 --no-second-order -o " + plain.string()), 0);
    const nlohmann::json q = read_json(plain);
    BOOST_CHECK(!q["options"]["second_order"].get<bool>());
    BOOST_CHECK_EQUAL(q["second_order_mode"].get<int>(), -1);
  }
  BOOST_CHECK_EQUAL(j["offset_rad"].size(), 2u);
  // A Kelvin-Voigt arm has no real poles: no real term is added.
  BOOST_CHECK_EQUAL(j["real_terms"].size(), 0u);
  BOOST_CHECK_EQUAL(j["options"]["real_terms"].get<int>(), 0);
  BOOST_CHECK_EQUAL(j["decay_ratio"].size(), 2u);
  BOOST_CHECK_EQUAL(j["decay_ratio"][0].get<double>(), 1.0);  // the reference mode
  // The ties are opt-in: none by default.
  BOOST_CHECK_EQUAL(j["options"]["frequency_tie"].get<double>(), 0.0);
  BOOST_CHECK(!j["options"]["frequency_tie_from_data"].get<bool>());
  BOOST_CHECK_EQUAL(j["frequency_ratio"][1].get<double>(), 1.0);
  {
    // Constant K scales neither frequency: the tie from the data holds, its ratio is the two
    // frequencies' (~1.4, the modes of K = [35 5; 5 20] N m/rad on the arm).
    const fs::path tied = scratch("frequency_tie.json");
    BOOST_REQUIRE_EQUAL(
        run(kTrial + " --angles th1,th2 --onset 2.5 --frequency-tie -1 -o " + tied.string()), 0);
    const nlohmann::json t = read_json(tied);
    BOOST_CHECK(t["options"]["frequency_tie_from_data"].get<bool>());
    BOOST_CHECK_GT(t["options"]["frequency_tie"].get<double>(), 0.0);
    const double ratio = t["frequency_ratio"][1].get<double>();
    const double f0 = t["f_hz"][0][100].get<double>(), f1 = t["f_hz"][1][100].get<double>();
    BOOST_TEST_MESSAGE("frequency ratio " << ratio << ", f " << f0 << " / " << f1 << " Hz");
    BOOST_CHECK_CLOSE(ratio, f1 / f0, 1.0);  // percent
  }
  const size_t frames = j["t_s"].size();
  BOOST_CHECK_GT(frames, 400u);  // ~2.4 s of free response at 200 Hz
  BOOST_CHECK_CLOSE(j["options"]["decimate_hz"].get<double>(), 200.0, 1e-12);
  BOOST_CHECK_EQUAL(j["valid"].size(), 2u);
  BOOST_CHECK_EQUAL(j["valid"][0].size(), frames);
  BOOST_CHECK_EQUAL(j["anr_db"][1].size(), frames);
  BOOST_CHECK_EQUAL(j["K_valid"].size(), frames);
  // Noise-free constant K0 = [35 5; 5 20] N m/rad: mid-record k11 within 1 %.
  BOOST_CHECK_CLOSE(j["K_nm_per_rad"][0][0][frames / 2].get<double>(), 35.0, 1.0);
  // The spectrogram map belongs to the spectrogram method only.
  const fs::path map = scratch("modal_map.csv");
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 2.5 -o " + out.string() +
                        " --spectrogram " + map.string()),
                    2);
  BOOST_CHECK(!fs::exists(map));
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 2.5 --method wavelet"), 2);
  BOOST_CHECK_EQUAL(j["options"]["design"], "whole");
  // K, C by eq 48 by default; the state-space mapping on request, from the same tracks. The
  // damping of the noise-free constant-K trial is classical: both give K0 within 1 %.
  BOOST_CHECK_EQUAL(j["options"]["mapping"], "eq48");
  const fs::path exact = scratch("state_space.json");
  BOOST_REQUIRE_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --mapping state_space -o " + exact.string()), 0);
  const nlohmann::json e = read_json(exact);
  BOOST_CHECK_EQUAL(e["options"]["mapping"], "state_space");
  BOOST_CHECK(e["f_hz"] == j["f_hz"]);
  BOOST_CHECK(e["K_nm_per_rad"] != j["K_nm_per_rad"]);
  BOOST_CHECK_CLOSE(e["K_nm_per_rad"][0][1][frames / 2].get<double>(), 5.0, 1.0);
  BOOST_CHECK_CLOSE(j["K_nm_per_rad"][0][1][frames / 2].get<double>(), 5.0, 1.0);
  std::string err;
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 2.5 --mapping complex", err), 2);
  BOOST_CHECK_MESSAGE(err.find("--mapping") != std::string::npos, err);
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 2.5 --method spectrogram --mapping "
                                 "state_space",
                        err),
                    2);
  BOOST_CHECK_MESSAGE(err.find("only the modal method") != std::string::npos, err);
  // Design (a), sliding windows: the same keys, estimates from half a window after the first
  // fitted sample to half a window before the last.
  const fs::path sliding = scratch("sliding.json");
  BOOST_REQUIRE_EQUAL(run(kTrial +
                          " --angles th1,th2 --onset 2.5 --design sliding "
                          "--sliding-window-s 0.5 -o " +
                          sliding.string()),
                      0);
  const nlohmann::json s = read_json(sliding);
  BOOST_CHECK_EQUAL(s["options"]["design"], "sliding");
  BOOST_CHECK_CLOSE(s["options"]["sliding_window_s"].get<double>(), 0.5, 1e-12);
  BOOST_CHECK_CLOSE(s["t_s"][0].get<double>() - j["t_s"][0].get<double>(), 0.25, 1e-6);
  BOOST_CHECK_EQUAL(s["t_s"].size(), frames - 100);
  BOOST_CHECK_EQUAL(s["K_nm_per_rad"][0][0].size(), s["t_s"].size());
  BOOST_CHECK_CLOSE(s["K_nm_per_rad"][0][0][s["t_s"].size() / 4].get<double>(), 35.0, 2.0);
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 2.5 --design windows"), 2);
  BOOST_CHECK_EQUAL(s["options"]["decay_tracks"], "alpha");  // the sliding design's only model
  // Decay splines: best by default, which runs both fits and reports both residuals and BICs,
  // keeping the lower BIC; alpha or gamma alone reports neither; anything else is refused by
  // name and nothing is written.
  BOOST_CHECK(j["options"]["decay_tracks_from_data"].get<bool>());
  BOOST_CHECK(s["decay_tracks_bic"].is_null());  // sliding: one model
  BOOST_CHECK(s["bic"].is_null());
  const fs::path alpha = scratch("decay_alpha.json"), gamma = scratch("decay_gamma.json");
  BOOST_REQUIRE_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --decay-tracks alpha -o " + alpha.string()), 0);
  BOOST_REQUIRE_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --decay-tracks gamma -o " + gamma.string()), 0);
  const nlohmann::json a = read_json(alpha), g = read_json(gamma);
  BOOST_CHECK_EQUAL(a["options"]["decay_tracks"], "alpha");
  BOOST_CHECK_EQUAL(g["options"]["decay_tracks"], "gamma");
  BOOST_CHECK(!a["options"]["decay_tracks_from_data"].get<bool>());
  BOOST_CHECK(a["decay_tracks_residual_rms_whitened"].is_null());
  BOOST_CHECK(g["decay_tracks_bic"].is_null());
  const nlohmann::json& both = j["decay_tracks_residual_rms_whitened"];
  const nlohmann::json& bics = j["decay_tracks_bic"];
  BOOST_REQUIRE(both.is_object() && bics.is_object());
  BOOST_CHECK_EQUAL(both["alpha"].get<double>(), a["residual_rms_whitened"].get<double>());
  BOOST_CHECK_EQUAL(both["gamma"].get<double>(), g["residual_rms_whitened"].get<double>());
  BOOST_CHECK_EQUAL(bics["alpha"].get<double>(), a["bic"].get<double>());
  BOOST_CHECK_EQUAL(bics["gamma"].get<double>(), g["bic"].get<double>());
  // The BIC from the reported residual and effective parameters, N = T x 2 whitened values.
  const double n = 2.0 * static_cast<double>(frames);
  const double rms = a["residual_rms_whitened"].get<double>();
  BOOST_CHECK_CLOSE(
      a["bic"].get<double>(),
      n * std::log(n * rms * rms) + std::log(n) * a["effective_parameters"].get<double>(), 1e-6);
  const bool gamma_kept = bics["gamma"].get<double>() < bics["alpha"].get<double>();
  BOOST_CHECK_EQUAL(j["options"]["decay_tracks"], gamma_kept ? "gamma" : "alpha");
  BOOST_CHECK(j["K_nm_per_rad"] == (gamma_kept ? g : a)["K_nm_per_rad"]);
  // The noise-free constant-K trial: the gamma model gives K0 within 1 % too.
  BOOST_CHECK_CLOSE(g["K_nm_per_rad"][0][0][frames / 2].get<double>(), 35.0, 1.0);
  const fs::path refused = scratch("decay_refused.json");
  BOOST_CHECK_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --decay-tracks rho -o " + refused.string(), err),
      2);
  BOOST_CHECK_MESSAGE(err.find("--decay-tracks") != std::string::npos, err);
  BOOST_CHECK(!fs::exists(refused));
}

BOOST_AUTO_TEST_CASE(auto_onset_defaults_to_the_fx_fy_channels) {
  // Without --forces, --onset auto reads the trial's fx, fy (the fixture's pulse starts at 2.5 s).
  const fs::path out = scratch("auto.json");
  BOOST_REQUIRE_EQUAL(
      run(kTrial + " --angles th1,th2 --onset auto --method spectrogram -o " + out.string()), 0);
  const nlohmann::json j = read_json(out);
  BOOST_CHECK_CLOSE(j["onset_s"].get<double>(), 2.5, 1e-6);
  BOOST_CHECK(j["options"]["forces"] == nlohmann::json({"fx", "fy"}));
  // A trial without them: exit 2, no output. The same record with the force columns dropped.
  const LineEdit first_three = [](const std::string& line) {  // t,th1,th2 kept
    std::size_t cut = line.find(',');
    for (int field = 0; field < 2; ++field) cut = line.find(',', cut + 1);
    return line.substr(0, cut);
  };
  const fs::path angles_only = fixture_copy("angles_only.csv", first_three, first_three);
  const fs::path none = scratch("none.json");
  BOOST_CHECK_EQUAL(run(angles_only.string() +
                        " --angles th1,th2 --onset 2.5 --method spectrogram -o " + none.string()),
                    0);  // the copy is a valid trial: only the onset detection needs forces
  fs::remove(none);
  BOOST_CHECK_EQUAL(
      run(angles_only.string() + " --angles th1,th2 --onset auto -o " + none.string()), 2);
  BOOST_CHECK(!fs::exists(none));
}

BOOST_AUTO_TEST_CASE(angles_recorded_in_degrees_are_converted_other_units_refused) {
  // The fixture with the shoulder angle written in degrees and the elbow's in mrad (header units
  // [deg], [mrad]): the same K and amplitudes as from rad, to the 15 digits written (K depends on
  // the ratio of the channels, so a unit left unconverted changes it); an angle channel in [m]
  // is refused with exit 2, no output.
  const fs::path deg = fixture_copy(
      "deg.csv",
      [](const std::string& line) {
        std::istringstream in(line);
        std::string t, th1, th2, rest;
        std::getline(in, t, ',');
        std::getline(in, th1, ',');
        std::getline(in, th2, ',');
        std::getline(in, rest);
        std::ostringstream row;
        row << std::setprecision(15) << t << ',' << std::stod(th1) * 180.0 / M_PI << ','
            << std::stod(th2) * 1e3 << ',' << rest;
        return row.str();
      },
      [](const std::string&) { return std::string("t,th1[deg],th2[mrad],fx[N],fy[N]"); });
  const fs::path metres = fixture_copy(
      "metres.csv", [](const std::string& line) { return line; },
      [](const std::string&) { return std::string("t,th1[m],th2[rad],fx[N],fy[N]"); });
  const fs::path from_rad = scratch("from_rad.json"), from_deg = scratch("from_deg.json");
  const std::string args = " --angles th1,th2 --onset 2.5 --method spectrogram -o ";
  BOOST_REQUIRE_EQUAL(run(kTrial + args + from_rad.string()), 0);
  BOOST_REQUIRE_EQUAL(run(deg.string() + args + from_deg.string()), 0);
  const nlohmann::json a = read_json(from_rad), b = read_json(from_deg);
  const std::size_t frames = a["t_s"].size();
  BOOST_REQUIRE_EQUAL(b["t_s"].size(), frames);
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 2; ++c) {
      const double ka = a["K_nm_per_rad"][r][c][frames / 2].get<double>();
      const double kb = b["K_nm_per_rad"][r][c][frames / 2].get<double>();
      BOOST_CHECK_SMALL(kb - ka, 1e-8 * std::abs(ka) + 1e-10);
      const double aa = a["amplitude"][r][c][frames / 2].get<double>();
      const double ab = b["amplitude"][r][c][frames / 2].get<double>();
      BOOST_CHECK_SMALL(ab - aa, 1e-8 * std::abs(aa) + 1e-14);
    }
  }
  const fs::path none = scratch("metres.json");
  BOOST_CHECK_EQUAL(run(metres.string() + args + none.string()), 2);
  BOOST_CHECK(!fs::exists(none));
}

BOOST_AUTO_TEST_CASE(subject_from_arm_parameters_or_a_simulation_spec) {
  // The same arm (upper arm 0.31 m, forearm 1.5 kg; the rest Table 1) given as parameters and as
  // a simulation spec's "arm": the same M(theta) and K, both different from the default arm's.
  const fs::path flat = scratch("flat.json"), sim = scratch("sim.json"),
                 endpoint = scratch("e.json");
  std::ofstream(flat) << R"({"l1_m": 0.31, "m2_kg": 1.5})";
  std::ofstream(sim) << R"({"model": "arm", "duration_s": 5, "sample_rate_hz": 4000,
                           "arm": {"l1_m": 0.31, "m2_kg": 1.5}})";
  std::ofstream(endpoint) << R"({"model": "endpoint", "duration_s": 5, "sample_rate_hz": 4000})";
  const std::string args = " --angles th1,th2 --onset 2.5 --method spectrogram -o ";
  const fs::path a = scratch("a.json"), b = scratch("b.json"), d = scratch("d.json");
  BOOST_REQUIRE_EQUAL(run(kTrial + args + a.string() + " --subject " + flat.string()), 0);
  BOOST_REQUIRE_EQUAL(run(kTrial + args + b.string() + " --subject " + sim.string()), 0);
  BOOST_REQUIRE_EQUAL(run(kTrial + args + d.string()), 0);
  const nlohmann::json ja = read_json(a), jb = read_json(b), jd = read_json(d);
  BOOST_CHECK(ja["options"]["arm"] == jb["options"]["arm"]);
  BOOST_CHECK_EQUAL(jb["options"]["arm"]["l1_m"].get<double>(), 0.31);
  BOOST_CHECK(ja["M_kg_m2"] == jb["M_kg_m2"]);
  BOOST_CHECK(ja["K_nm_per_rad"] == jb["K_nm_per_rad"]);
  BOOST_CHECK(ja["M_kg_m2"] != jd["M_kg_m2"]);
  const fs::path none = scratch("none_subject.json");
  BOOST_CHECK_EQUAL(run(kTrial + args + none.string() + " --subject " + endpoint.string()), 2);
  BOOST_CHECK(!fs::exists(none));
}

BOOST_AUTO_TEST_CASE(a_trial_without_time_column_needs_fs) {
  // The fixture (2 kHz, t from 2.0 s) without its t column: with --fs 2000 time starts at 0, so the
  // onset is 0.5 s and the same K comes out 2 s earlier; without --fs, exit 2 and no output.
  const LineEdit without_t = [](const std::string& line) {
    return line.substr(line.find(',') + 1);
  };
  const fs::path untimed = fixture_copy("untimed.csv", without_t, without_t);
  const std::string args = " --angles th1,th2 --method spectrogram -o ";
  const fs::path a = scratch("timed.json"), b = scratch("untimed.json");
  BOOST_REQUIRE_EQUAL(run(kTrial + args + a.string() + " --onset 2.5"), 0);
  BOOST_CHECK_EQUAL(run(untimed.string() + args + b.string() + " --onset 0.5"), 2);
  BOOST_CHECK(!fs::exists(b));
  BOOST_REQUIRE_EQUAL(run(untimed.string() + args + b.string() + " --onset 0.5 --fs 2000"), 0);
  const nlohmann::json ja = read_json(a), jb = read_json(b);
  BOOST_REQUIRE_EQUAL(ja["t_s"].size(), jb["t_s"].size());
  BOOST_CHECK_CLOSE(jb["t_s"][0].get<double>() + 2.0, ja["t_s"][0].get<double>(), 1e-9);
  const std::size_t mid = ja["t_s"].size() / 2;
  BOOST_CHECK_CLOSE(jb["K_nm_per_rad"][0][0][mid].get<double>(),
                    ja["K_nm_per_rad"][0][0][mid].get<double>(), 1e-6);
}

BOOST_AUTO_TEST_CASE(bad_input_exits_2_without_writing) {
  const fs::path out = scratch("bad.json");
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,elbow --onset 2.5 -o " + out.string()), 2);
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 9 -o " + out.string()), 2);
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 4.6 -o " + out.string()), 2);
  // The trial ends at 5.0 s: a pulse from 4.99 s (--pulse-s 0.02) leaves no free response, and the
  // message says so in the trial's units (not "ends -0.010000 s after the pulse").
  std::string why;
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 4.99 -o " + out.string(), why), 2);
  BOOST_CHECK_MESSAGE(why.find("the pulse ends at 5.01 s") != std::string::npos &&
                          why.find("(5 s)") != std::string::npos,
                      why);
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset soon -o " + out.string()), 2);
  BOOST_CHECK_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --window blackman -o " + out.string()), 2);
  BOOST_CHECK_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --real-terms 1000 -o " + out.string()), 2);
  BOOST_CHECK_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --design sliding --sliding-window-s -1 -o " +
          out.string()),
      2);
  const fs::path spec = scratch("subject.json");
  std::ofstream(spec) << "{\"l1_m\": 0.3, \"mass\": 2}";
  BOOST_CHECK_EQUAL(run(kTrial + " --angles th1,th2 --onset 2.5 --subject " + spec.string() +
                        " -o " + out.string()),
                    2);
  BOOST_CHECK(!fs::exists(out));
}

// The run's warnings are in the JSON (`warnings`, [] when none) as well as on stderr: the posture
// trial has none; the same trial with the elbow turning at 0.2 rad/s throughout (a movement
// trial, analysed without --baseline) is named with that rate.
BOOST_AUTO_TEST_CASE(warnings_are_listed_in_the_json_as_on_stderr) {
  const fs::path rest = scratch("rest.json");
  BOOST_REQUIRE_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --method spectrogram -o " + rest.string()), 0);
  BOOST_CHECK(read_json(rest)["warnings"] == nlohmann::json::array());

  const fs::path moving = fixture_copy("moving.csv", [](const std::string& line) {
    const auto [t, th1, th2, fx, fy] = fields(line);
    std::ostringstream row;
    row << std::setprecision(17) << t << ',' << th1 << ',' << th2 + 0.2 * t << ',' << fx << ','
        << fy;
    return row.str();
  });
  const fs::path json = scratch("moving.json");
  std::string err;
  BOOST_REQUIRE_EQUAL(
      run(moving.string() + " --angles th1,th2 --onset 2.5 --method spectrogram -o " +
              json.string(),
          err),
      0);
  const nlohmann::json warnings = read_json(json)["warnings"];
  BOOST_REQUIRE_EQUAL(warnings.size(), 1u);
  const std::string w = warnings[0];
  BOOST_CHECK(w.find("'th2' 0.2 rad/s") != std::string::npos);
  BOOST_CHECK(w.find("'th1'") == std::string::npos);
  BOOST_CHECK(w.find("--baseline") != std::string::npos);
  BOOST_CHECK(err.find(w) != std::string::npos);
}

// A trial with less than --noise-window-s before the onset: the modal fit takes the noise from
// what there is, says so on stderr and in `warnings`, and `options.noise_window_s` is the span
// used. The fixture starts at 2.0 s (0.5 s before the onset, less 0.05 s for the filter: 0.45 s);
// cut at 2.25 s it holds 0.2 s; a window it holds (--noise-window-s 0.4) gives no warning.
BOOST_AUTO_TEST_CASE(a_short_noise_window_is_reported_as_used) {
  const fs::path cut = fixture_copy("cut.csv", [](const std::string& line) {
    return fields(line)[0] >= 2.25 - 1e-9 ? line : std::string();
  });
  for (const auto& [trial, used] : {std::pair{kTrial, 0.45}, std::pair{cut.string(), 0.2}}) {
    const fs::path json = scratch("short.json");
    std::string err;
    BOOST_REQUIRE_EQUAL(run(trial + " --angles th1,th2 --onset 2.5 -o " + json.string(), err), 0);
    const nlohmann::json out = read_json(json);
    BOOST_CHECK_CLOSE(out["options"]["noise_window_s"].get<double>(), used, 1e-6);
    const nlohmann::json warnings = out["warnings"];
    BOOST_REQUIRE_EQUAL(warnings.size(), 1u);
    const std::string w = warnings[0];
    std::ostringstream span;
    span << used << " s before the onset";
    BOOST_CHECK_MESSAGE(w.find(span.str()) != std::string::npos, w);
    BOOST_CHECK(w.find("--noise-window-s 1 s asked") != std::string::npos);
    BOOST_CHECK(err.find(w) != std::string::npos);
  }
  const fs::path held = scratch("held.json");
  BOOST_REQUIRE_EQUAL(
      run(kTrial + " --angles th1,th2 --onset 2.5 --noise-window-s 0.4 -o " + held.string()), 0);
  const nlohmann::json out = read_json(held);
  BOOST_CHECK_EQUAL(out["options"]["noise_window_s"].get<double>(), 0.4);
  BOOST_CHECK(out["warnings"] == nlohmann::json::array());

  // The angles held at their first values: no response, the fit fails (exit 1, no output, a
  // message that says what is missing), and the short window's warning is printed before it.
  std::string first;  // ",th1,th2" of the first row
  const fs::path flat = fixture_copy("flat.csv", [&first](const std::string& line) {
    const std::size_t time_end = line.find(','), angles_end = line.find(',', time_end + 1);
    const std::size_t forces = line.find(',', angles_end + 1);
    if (first.empty()) first = line.substr(time_end, forces - time_end);
    return line.substr(0, time_end) + first + line.substr(forces);
  });
  const fs::path failed = scratch("flat.json");
  std::string err;
  BOOST_CHECK_EQUAL(run(flat.string() + " --angles th1,th2 --onset 2.5 -o " + failed.string(), err),
                    1);
  BOOST_CHECK(!fs::exists(failed));
  BOOST_CHECK_MESSAGE(
      err.find("2 damped oscillations not found in the free response") != std::string::npos, err);
  const std::size_t warned = err.find("0.45 s before the onset"), failure = err.find("failed");
  BOOST_CHECK_MESSAGE(
      warned != std::string::npos && failure != std::string::npos && warned < failure, err);
}
