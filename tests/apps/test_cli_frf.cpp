#include <sys/wait.h>

#include <Eigen/Dense>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <complex>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <set>
#include <sstream>

#include "tests/support/support.hpp"

namespace fs = std::filesystem;
using stiffid::test::read_text;

namespace {

const std::string kTrial = std::string(STIFFID_TEST_DATA_DIR) + "/mimo/mimo_endpoint_c25_snr20.csv";

struct Run {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

// A scratch folder per test case, removed at the end.
using Scratch = stiffid::test::TempFolder;

Run run_stiffid(const std::string& args, const Scratch& scratch) {
  const fs::path out = scratch.path / "stdout.txt";
  const fs::path err = scratch.path / "stderr.txt";
  const std::string command = std::string("\"") + STIFFID_BINARY + "\" frf " + args + " >\"" +
                              out.string() + "\" 2>\"" + err.string() + "\"";
  const int status = std::system(command.c_str());
  Run r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = read_text(out);
  r.err = read_text(err);
  return r;
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

std::set<std::string> keys(const nlohmann::json& j) {
  std::set<std::string> k;
  for (auto it = j.begin(); it != j.end(); ++it) k.insert(it.key());
  return k;
}

}  // namespace

BOOST_AUTO_TEST_CASE(writes_the_contract_keys_to_a_file) {
  const Scratch s("cli_frf");
  const fs::path json = s.path / "frf.json";
  const Run r = run_stiffid("\"" + kTrial +
                                "\" --inputs fx,fy --outputs x,y --nfft 256 --overlap 0.5 "
                                "-o \"" +
                                json.string() + "\"",
                            s);
  BOOST_REQUIRE_EQUAL(r.exit_code, 0);
  const auto j = nlohmann::json::parse(read_text(json));
  BOOST_CHECK((keys(j) == std::set<std::string>{"fs", "nfft", "segments", "inputs", "outputs",
                                                "frequency_hz", "frf", "coherence",
                                                "condition_number", "random_error"}));
  BOOST_CHECK_EQUAL(j["fs"].get<double>(), 50.0);
  BOOST_CHECK_EQUAL(j["nfft"].get<int>(), 256);
  BOOST_CHECK_EQUAL(j["segments"].get<int>(), (3000 - 128) / 128);  // scipy's count
  const size_t bins = j["frequency_hz"].size();
  BOOST_CHECK_EQUAL(bins, 129u);
  BOOST_CHECK_EQUAL(j["condition_number"].size(), bins);
  for (const std::string y : {"x", "y"}) {
    BOOST_CHECK_EQUAL(j["coherence"]["multiple"][y].size(), bins);
    for (const std::string x : {"fx", "fy"}) {
      BOOST_CHECK_EQUAL(j["frf"][y][x]["re"].size(), bins);
      BOOST_CHECK_EQUAL(j["frf"][y][x]["im"].size(), bins);
      BOOST_CHECK_EQUAL(j["coherence"]["ordinary"][y][x].size(), bins);
      BOOST_CHECK_EQUAL(j["coherence"]["partial"][y][x].size(), bins);
      for (const std::string k : {"eps", "lower", "upper"}) {
        BOOST_CHECK_EQUAL(j["random_error"]["frf_magnitude"][y][x][k].size(), bins);
        BOOST_CHECK_EQUAL(j["random_error"]["coherence"]["ordinary"][y][x][k].size(), bins);
        BOOST_CHECK_EQUAL(j["random_error"]["coherence"]["partial"][y][x][k].size(), bins);
      }
    }
    BOOST_CHECK_EQUAL(j["random_error"]["coherence"]["multiple"][y]["eps"].size(), bins);
  }
  BOOST_CHECK_EQUAL(j["random_error"]["averages"].get<double>(), 22.0);
}

// The reference (scipy, full-precision signals) in the excitation band below 12 Hz, where the
// 10-digit CSV rounding changes H by < 1e-8 relative (see estimators/test_frf.cpp); the JSON
// carries 17 significant digits.
BOOST_AUTO_TEST_CASE(stdout_json_matches_the_reference_frf) {
  const Scratch s("cli_frf");
  const Run r = run_stiffid("\"" + kTrial + "\" --inputs fx,fy --outputs x,y", s);
  BOOST_REQUIRE_EQUAL(r.exit_code, 0);
  const auto j = nlohmann::json::parse(r.out);
  std::ifstream in(std::string(STIFFID_TEST_DATA_DIR) + "/mimo/mimo_endpoint_c25_snr20.ref.json");
  const auto ref = nlohmann::json::parse(in);
  const auto f = j["frequency_hz"].get<std::vector<double>>();
  for (const std::string y : {"x", "y"}) {
    for (const std::string x : {"fx", "fy"}) {
      for (size_t k = 0; k < f.size() && f[k] <= 12.0; ++k) {
        const std::complex<double> got(j["frf"][y][x]["re"][k].get<double>(),
                                       j["frf"][y][x]["im"][k].get<double>());
        const std::complex<double> want(ref["frf"][y][x]["re"][k].get<double>(),
                                        ref["frf"][y][x]["im"][k].get<double>());
        BOOST_CHECK_LE(std::abs(got - want), 1e-6 * std::abs(want));
      }
    }
  }
}

// Stiffness = per-frequency inverse of the compliance: K(f) H(f) = I up to round-off (1e-9 for
// condition numbers of H below ~1e4 here).
BOOST_AUTO_TEST_CASE(stiffness_flag_writes_the_inverse_matrix) {
  const Scratch s("cli_frf");
  const Run r = run_stiffid("\"" + kTrial + "\" --inputs fx,fy --outputs x,y --stiffness", s);
  BOOST_REQUIRE_EQUAL(r.exit_code, 0);
  const auto j = nlohmann::json::parse(r.out);
  BOOST_REQUIRE(j.contains("stiffness"));
  const std::vector<std::string> in = {"fx", "fy"}, out = {"x", "y"};
  for (size_t k = 1; k < 60; ++k) {
    Eigen::Matrix2cd h, K;
    for (int a = 0; a < 2; ++a) {
      for (int b = 0; b < 2; ++b) {
        h(a, b) = {j["frf"][out[a]][in[b]]["re"][k].get<double>(),
                   j["frf"][out[a]][in[b]]["im"][k].get<double>()};
        K(a, b) = {j["stiffness"][in[a]][out[b]]["re"][k].get<double>(),
                   j["stiffness"][in[a]][out[b]]["im"][k].get<double>()};
      }
    }
    BOOST_CHECK_SMALL((K * h - Eigen::Matrix2cd::Identity()).norm(), 1e-9);
  }
}

BOOST_AUTO_TEST_CASE(missing_column_is_exit_2_naming_file_and_column) {
  const Scratch s("cli_frf");
  const fs::path json = s.path / "frf.json";
  const Run r = run_stiffid(
      "\"" + kTrial + "\" --inputs fx,fz --outputs x,y -o \"" + json.string() + "\"", s);
  BOOST_CHECK_EQUAL(r.exit_code, 2);
  BOOST_CHECK(contains(r.err, "mimo_endpoint_c25_snr20.csv"));
  BOOST_CHECK(contains(r.err, "'fz'"));
  BOOST_CHECK(contains(r.err, "--inputs"));
  BOOST_CHECK(!fs::exists(json));
}

BOOST_AUTO_TEST_CASE(too_few_samples_for_nfft_is_exit_2_naming_the_file) {
  const Scratch s("cli_frf");
  const Run r = run_stiffid("\"" + kTrial + "\" --inputs fx,fy --outputs x,y --nfft 4096", s);
  BOOST_CHECK_EQUAL(r.exit_code, 2);
  BOOST_CHECK(contains(r.err, "mimo_endpoint_c25_snr20.csv"));
  BOOST_CHECK(contains(r.err, "4096"));
  BOOST_CHECK(r.out.empty());
}

BOOST_AUTO_TEST_CASE(bad_window_detrend_and_overlap_are_exit_2_naming_the_flag) {
  const Scratch s("cli_frf");
  for (const auto& [flag, value] :
       std::vector<std::pair<std::string, std::string>>{{"--window", "kaiser:abc"},
                                                        {"--window", "triangle"},
                                                        {"--detrend", "quadratic"},
                                                        {"--overlap", "1.5"},
                                                        {"--nfft", "1"}}) {
    const Run r =
        run_stiffid("\"" + kTrial + "\" --inputs fx,fy --outputs x,y " + flag + " " + value, s);
    BOOST_TEST_CONTEXT(flag << " " << value) {
      BOOST_CHECK_EQUAL(r.exit_code, 2);
      BOOST_CHECK(contains(r.err, flag));
    }
  }
}

// fy = 2 fx exactly: Gxx is singular at every frequency, the FRF is not identifiable.
BOOST_AUTO_TEST_CASE(perfectly_coupled_inputs_are_exit_1_with_a_message_and_no_file) {
  const Scratch s("cli_frf");
  const fs::path csv = s.path / "coupled.csv";
  {
    std::ofstream out(csv);
    out << "t,fx,fy,x,y\n";
    std::mt19937_64 rng(3);
    std::normal_distribution<double> normal;
    out.precision(17);
    double prev = 0.0;
    for (int t = 0; t < 2048; ++t) {
      const double fx = normal(rng);
      out << t * 0.01 << ',' << fx << ',' << 2.0 * fx << ',' << 0.5 * fx + 0.3 * prev << ','
          << normal(rng) << '\n';
      prev = fx;
    }
  }
  const fs::path json = s.path / "frf.json";
  const Run r = run_stiffid(
      "\"" + csv.string() + "\" --inputs fx,fy --outputs x,y -o \"" + json.string() + "\"", s);
  BOOST_CHECK_EQUAL(r.exit_code, 1);
  BOOST_CHECK(contains(r.err, "perfectly coupled"));
  BOOST_CHECK(contains(r.err, "coupled.csv"));
  BOOST_CHECK(!fs::exists(json));
}
