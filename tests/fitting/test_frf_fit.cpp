// Lumped-model fits to frequency responses (fitting/frf_fit.hpp): exact compliances of known
// Kelvin-Voigt and Poynting-Thomson systems written out in closed form here (complex algebra with
// std::complex, independent of the fit's real-block solves), coherence gating, bad input, and the
// chain `stiffid simulate` -> `stiffid frf` -> `stiffid fit --frf` against the simulator's truth.
#include <sys/wait.h>

#include <Eigen/Dense>
#include <boost/test/unit_test.hpp>
#include <cmath>
#include <complex>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "data/error.hpp"
#include "fitting/frf_fit.hpp"
#include "tests/support/support.hpp"

namespace fit = stiffid::fitting;
namespace fs = std::filesystem;
using cd = std::complex<double>;

namespace {

const Eigen::Matrix2d kI = (Eigen::Matrix2d() << 1.2, 0.1, 0.1, 0.9).finished();        // kg
const Eigen::Matrix2d kC = (Eigen::Matrix2d() << 10.0, 1.0, 1.0, 7.0).finished();       // N s/m
const Eigen::Matrix2d kK = (Eigen::Matrix2d() << 250.0, 40.0, 40.0, 180.0).finished();  // N/m

// Dynamic stiffness Z(i omega) in closed form; H = Z^-1.
Eigen::Matrix2cd kv_stiffness(double w) {
  return (kK - w * w * kI).cast<cd>() + cd(0.0, w) * kC.cast<cd>();
}
Eigen::Matrix2cd pt_stiffness(double w, const Eigen::Matrix2d& ks, const Eigen::Matrix2d& kp,
                              const Eigen::Matrix2d& cp) {
  const Eigen::Matrix2cd series = (ks + kp).cast<cd>() + cd(0.0, w) * cp.cast<cd>();
  return (ks - w * w * kI).cast<cd>() - ks.cast<cd>() * series.inverse() * ks.cast<cd>();
}

template <typename Z>
fit::FrfTarget exact_target(Z stiffness, double f_lo, double f_hi, int count) {
  fit::FrfTarget t;
  t.source = "exact";
  t.inputs = {"fx", "fy"};
  t.outputs = {"x", "y"};
  t.frequency_hz = Eigen::VectorXd::LinSpaced(count, f_lo, f_hi);
  t.coherence = Eigen::MatrixXd::Ones(count, 2);
  for (int k = 0; k < count; ++k)
    t.compliance.push_back(stiffness(2 * M_PI * t.frequency_hz(k)).inverse());
  return t;
}

double relative_error(const fit::LumpedFitResult& r, const std::string& name,
                      const Eigen::Matrix2d& truth) {
  for (const auto& m : r.parameters) {
    if (m.name == name)
      return (m.value - truth).cwiseAbs().maxCoeff() / truth.cwiseAbs().maxCoeff();
  }
  return INFINITY;
}

int run(const std::string& args) {
  const int status =
      std::system((std::string(STIFFID_BINARY) + " " + args + " 2>/dev/null").c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

BOOST_AUTO_TEST_CASE(kelvin_voigt_from_its_exact_compliance) {
  const fit::FrfTarget t = exact_target(kv_stiffness, 0.1, 10.0, 100);
  const fit::LumpedFitResult r = fit::fit_frf(t, {});
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_CHECK_EQUAL(r.target, "frf");
  BOOST_CHECK_LT(relative_error(r, "I", kI), 1e-6);
  BOOST_CHECK_LT(relative_error(r, "C", kC), 1e-6);
  BOOST_CHECK_LT(relative_error(r, "K", kK), 1e-6);
  BOOST_CHECK_CLOSE(r.vaf_percent(0), 100.0, 1e-6);
  BOOST_CHECK_CLOSE(r.vaf_percent(1), 100.0, 1e-6);
}

BOOST_AUTO_TEST_CASE(poynting_thomson_from_its_exact_compliance) {
  const Eigen::Matrix2d ks = (Eigen::Matrix2d() << 600, 50, 50, 400).finished();
  const Eigen::Matrix2d kp = (Eigen::Matrix2d() << 150, 20, 20, 100).finished();
  const Eigen::Matrix2d cp = (Eigen::Matrix2d() << 30, 3, 3, 20).finished();
  const fit::FrfTarget t =
      exact_target([&](double w) { return pt_stiffness(w, ks, kp, cp); }, 0.1, 15.0, 150);
  fit::FrfFitOptions o;
  o.model = fit::LumpedModel::poynting_thomson;
  const fit::LumpedFitResult r = fit::fit_frf(t, o);
  BOOST_REQUIRE_MESSAGE(r.status.ok, r.status.message);
  BOOST_CHECK_LT(relative_error(r, "I", kI), 1e-5);
  BOOST_CHECK_LT(relative_error(r, "KS", ks), 1e-5);
  BOOST_CHECK_LT(relative_error(r, "KP", kp), 1e-5);
  BOOST_CHECK_LT(relative_error(r, "CP", cp), 1e-5);
}

BOOST_AUTO_TEST_CASE(incoherent_frequencies_are_left_out) {
  fit::FrfTarget t = exact_target(kv_stiffness, 0.1, 10.0, 100);
  // Every third frequency corrupted, with a multiple coherence below the threshold.
  for (int k = 0; k < 100; k += 3) {
    t.compliance[k] *= 5.0;
    t.coherence.row(k).setConstant(0.2);
  }
  const fit::LumpedFitResult r = fit::fit_frf(t, {});
  BOOST_REQUIRE(r.status.ok);
  BOOST_CHECK_LT(relative_error(r, "K", kK), 1e-6);
  fit::FrfFitOptions all;
  all.min_coherence = 0.0;  // now they count (weighted by sqrt(0.2)) and bias K
  BOOST_CHECK_GT(relative_error(fit::fit_frf(t, all), "K", kK), 1e-2);
}

BOOST_AUTO_TEST_CASE(bad_input_is_an_input_error) {
  const fit::FrfTarget t = exact_target(kv_stiffness, 0.1, 10.0, 100);
  fit::FrfFitOptions o;
  o.model = fit::LumpedModel::duffing;
  BOOST_CHECK_THROW(fit::fit_frf(t, o), stiffid::InputError);
  fit::FrfFitOptions band;
  band.band_low_hz = 20.0;  // no frequency there
  BOOST_CHECK_THROW(fit::fit_frf(t, band), stiffid::InputError);
  const stiffid::test::TempFolder folder("frf_fit");
  const fs::path& dir = folder.path;
  std::ofstream(dir / "bad.json")
      << R"({"inputs": ["fx"], "outputs": ["x"], "frequency_hz": [1, 2]})";
  BOOST_CHECK_THROW(fit::read_frf_json((dir / "bad.json").string()), stiffid::InputError);
  BOOST_CHECK_THROW(fit::read_frf_json((dir / "missing.json").string()), stiffid::InputError);
}

BOOST_AUTO_TEST_CASE(cli_chain_recovers_the_simulated_endpoint_model) {
  // 60 s at 50 Hz of the reference endpoint model (I, B, K above; exact FOH discretization), no
  // noise; Welch FRF with 512-point segments; KV fit over 0.2-12 Hz. What remains is the Welch
  // bias (leakage) and the sampled-vs-continuous response: within 2 % of the truth.
  const stiffid::test::TempFolder folder("frf_cli");
  const fs::path& dir = folder.path;
  const std::string spec =
      std::string(STIFFID_SOURCE_DIR) + "/models/specs/perreault_endpoint_c0.json";
  const std::string trial = (dir / "trial.csv").string(), frf = (dir / "frf.json").string(),
                    out = (dir / "fit.json").string();
  BOOST_REQUIRE_EQUAL(run("simulate " + spec + " -o " + trial), 0);
  BOOST_REQUIRE_EQUAL(run("frf " + trial + " --inputs fx,fy --outputs x,y --nfft 512 -o " + frf),
                      0);
  BOOST_REQUIRE_EQUAL(run("fit kv --frf " + frf + " --band 0.2:12 -o " + out), 0);
  std::ifstream in(out);
  const nlohmann::json j = nlohmann::json::parse(in);
  BOOST_CHECK_EQUAL(j["target"], "frf");
  for (const auto& [name, truth] : {std::pair{"I", kI}, {"C", kC}, {"K", kK}}) {
    Eigen::Matrix2d v;
    for (int r = 0; r < 2; ++r)
      for (int c = 0; c < 2; ++c) v(r, c) = j["parameters"][name]["value"][r][c].get<double>();
    const double e = (v - truth).cwiseAbs().maxCoeff() / truth.cwiseAbs().maxCoeff();
    BOOST_TEST_MESSAGE(name << " relative error " << e);
    BOOST_CHECK_LT(e, 0.02);
  }
  BOOST_CHECK_EQUAL(run("fit duffing --frf " + frf), 2);
  BOOST_CHECK_EQUAL(run("fit kv --frf " + frf + " --band 5:1"), 2);
}
