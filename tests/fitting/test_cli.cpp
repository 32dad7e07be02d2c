// `stiffid fit` and `stiffid regress` end to end: JSON contract of issue 8 and exit codes
// (0 success, 1 numerical failure, 2 bad input), on the scipy fixtures of tests/data/fitting.

#include <sys/wait.h>

#include <boost/test/unit_test.hpp>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "tests/support/support.hpp"

namespace {

const std::string kDir = std::string(STIFFID_TEST_DATA_DIR) + "/fitting/";

int run(const std::string& args) {
  const std::string cmd = std::string(STIFFID_BINARY) + " " + args + " 2>/dev/null";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A fresh path `name` in this test program's temporary folder (removed when the program ends).
std::string temp(const std::string& name) {
  static const stiffid::test::TempFolder folder("fit_cli");
  std::filesystem::remove(folder.path / name);
  return folder.file(name);
}

nlohmann::json read(const std::string& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

}  // namespace

BOOST_AUTO_TEST_CASE(fit_writes_the_issue_json) {
  const std::string out = temp("kv2.json");
  BOOST_TEST(run("fit kv " + kDir +
                 "kv2.csv --inputs f1,f2 --outputs x1,x2 --starts 2 --seed 3 -o " + out) == 0);
  const nlohmann::json j = read(out);
  BOOST_TEST(j.at("model") == "kv");
  BOOST_TEST(j.at("dof") == 2);
  BOOST_TEST(j.at("status") == true);
  BOOST_TEST(j.at("starts") == 2);
  BOOST_TEST(j.at("iterations").get<int>() > 0);
  BOOST_TEST(j.at("termination").get<std::string>().find("CONVERGENCE") == 0u);
  BOOST_TEST(j.at("vaf_percent").size() == 2u);
  for (const char* name : {"I", "C", "K"}) {
    BOOST_TEST(j.at("parameters").at(name).at("value").size() == 2u);
    BOOST_TEST(j.at("parameters").at(name).at("std_error")[0].size() == 2u);
  }
  BOOST_TEST(j.at("parameters").at("I").at("unit") == "kg");
  BOOST_TEST(j.at("parameters").at("K").at("unit") == "N/m");
  // fixture truth K = [[500, 100], [100, 300]] N/m
  BOOST_TEST(std::abs(j["parameters"]["K"]["value"][0][0].get<double>() - 500.0) < 0.05);
}

BOOST_AUTO_TEST_CASE(fit_one_dof_gives_matrices) {
  const std::string out = temp("pt1.json");
  BOOST_TEST(run("fit pt " + kDir + "pt1.csv --inputs f1 --outputs x1 --starts 1 -o " + out) == 0);
  const nlohmann::json j = read(out);
  BOOST_TEST(j["parameters"]["KS"]["value"][0].size() == 1u);
}

BOOST_AUTO_TEST_CASE(fit_bad_input_exits_2_and_non_convergence_exits_1_without_output) {
  const std::string out = temp("bad.json");
  BOOST_TEST(run("fit maxwell " + kDir + "kv1.csv --inputs f1 --outputs x1 -o " + out) == 2);
  BOOST_TEST(run("fit kv " + kDir + "kv1.csv --inputs f1,f2 --outputs x1 -o " + out) == 2);
  BOOST_TEST(run("fit kv " + kDir + "kv1.csv --inputs f1 --outputs x1 --hold cubic -o " + out) ==
             2);
  BOOST_TEST(run("fit kv " + kDir +
                 "kv2.csv --inputs f1,f2 --outputs x1,x2 --starts 1 "
                 "--max-iterations 1 -o " +
                 out) == 1);
  BOOST_TEST(!std::filesystem::exists(out));
}

BOOST_AUTO_TEST_CASE(regress_writes_the_issue_json) {
  const std::string out = temp("regress.json");
  std::string files;
  for (const char* onset : {"2.5", "3.0"}) {
    for (int d = 0; d < 8; ++d)
      files += " " + kDir + "pulse_" + onset + "_d" + std::to_string(d) + ".csv";
  }
  BOOST_TEST(run("regress force-pulse" + files + " -o " + out) == 0);
  const nlohmann::json j = read(out);
  BOOST_TEST(j.at("method") == "force-pulse");
  BOOST_TEST(j.at("estimates").size() == 2u);
  const nlohmann::json& e = j["estimates"][0];
  for (const char* key :
       {"onset_s", "trials", "K_endpoint_n_per_m", "B_endpoint_ns_per_m", "M_endpoint_kg",
        "K_joint_nm_per_rad", "B_joint_nms_per_rad", "residual_rms"}) {
    BOOST_TEST(e.contains(key), key);
  }
  BOOST_TEST(std::abs(e["K_endpoint_n_per_m"][0][0].get<double>() - 600.0) < 6.0);  // 1 %
  BOOST_TEST(j.at("profile").at("t_s").size() > 2u);
  BOOST_TEST(j["profile"]["K_joint_nm_per_rad"][0][0].size() == j["profile"]["t_s"].size());
  // one direction is fewer than the unknowns: exit 2
  BOOST_TEST(run("regress force-pulse " + kDir + "pulse_2.5_d0.csv -o " + out + "x") == 2);
  BOOST_TEST(run("regress sideways " + kDir + "pulse_2.5_d0.csv") == 2);
}
