// `stiffid anova` end to end: exit codes, clean JSON on stdout, table placement, no partial file.

#include <sys/wait.h>

#include <boost/test/unit_test.hpp>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "tests/support/support.hpp"

namespace fs = std::filesystem;
using stiffid::test::read_text;

namespace {

const std::string kDir = std::string(STIFFID_TEST_DATA_DIR) + "/anova/";

struct Run {
  int code = -1;
  std::string out, err;
};

// This test program's temporary folder (removed when the program ends).
const fs::path& scratch() {
  static const stiffid::test::TempFolder folder("anova_cli");
  return folder.path;
}

Run run(const std::string& args) {
  const fs::path dir = scratch();
  const std::string cmd = std::string(STIFFID_BINARY) + " anova " + args + " >" +
                          (dir / "out").string() + " 2>" + (dir / "err").string();
  const int status = std::system(cmd.c_str());
  Run r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = read_text(dir / "out");
  r.err = read_text(dir / "err");
  return r;
}

fs::path write(const std::string& name, const std::string& text) {
  const fs::path p = scratch() / name;
  std::ofstream(p) << text;
  return p;
}

}  // namespace

BOOST_AUTO_TEST_CASE(json_on_stdout_is_clean_and_matches_the_reference) {
  const Run r = run(kDir + "anova_public_twoway.csv --dv err --subject id --within method,noise");
  BOOST_REQUIRE_EQUAL(r.code, 0);
  const auto j = nlohmann::json::parse(r.out);  // throws if the table leaked into stdout
  std::ifstream in(kDir + "anova_public_twoway.ref.json");
  const auto ref = nlohmann::json::parse(in);
  BOOST_REQUIRE_EQUAL(j["effects"].size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    BOOST_CHECK_EQUAL(j["effects"][i]["effect"], ref["effects"][i]["effect"]);
    // JSON carries 17 significant digits; 1e-8 relative is the contract.
    const double f = j["effects"][i]["F"], f_ref = ref["effects"][i]["F"];
    BOOST_CHECK_CLOSE_FRACTION(f, f_ref, 1e-8);
  }
  BOOST_CHECK(r.err.find("Effect") != std::string::npos);  // the table went to stderr
}

BOOST_AUTO_TEST_CASE(output_file_gets_json_and_stdout_the_table) {
  const fs::path out = scratch() / "res.json";
  const Run r =
      run(kDir + "oneway.csv --dv err --subject id --within method --pairwise method -o " +
          out.string());
  BOOST_REQUIRE_EQUAL(r.code, 0);
  BOOST_CHECK(r.out.find("method") != std::string::npos);
  BOOST_CHECK(r.out.find("Mauchly") != std::string::npos);
  const auto j = nlohmann::json::parse(read_text(out));
  BOOST_CHECK_EQUAL(j["pairwise"].size(), 6u);
  BOOST_CHECK_EQUAL(j["mauchly"][0]["effect"], "method");
}

BOOST_AUTO_TEST_CASE(random_design_command_line) {
  const Run r = run(kDir +
                    "random3.csv --dv err --fixed method --random kprofile,cprofile "
                    "--mixed-model restricted");
  BOOST_REQUIRE_EQUAL(r.code, 0);
  const auto j = nlohmann::json::parse(r.out);
  BOOST_CHECK_EQUAL(j["effects"][0]["effect"], "method");
  BOOST_CHECK_EQUAL(j["effects"][0]["type"], "fixed");
  BOOST_CHECK_EQUAL(j["effects"][0]["quasi"], true);
  BOOST_CHECK(!j["effects"][0].contains("pes"));
  BOOST_CHECK_EQUAL(j["effects"][1]["type"], "random");
}

BOOST_AUTO_TEST_CASE(missing_cell_exits_2_naming_subject_and_cell) {
  const fs::path data = write("missing.csv", "id,m,err\ns1,a,1\ns1,b,2\ns2,a,3\ns3,a,1\ns3,b,4\n");
  const Run r = run(data.string() + " --dv err --subject id --within m");
  BOOST_CHECK_EQUAL(r.code, 2);
  BOOST_CHECK(r.err.find("subject 's2'") != std::string::npos);
  BOOST_CHECK(r.err.find("m=b") != std::string::npos);
  BOOST_CHECK(r.out.empty());
}

BOOST_AUTO_TEST_CASE(zero_error_variance_exits_1_and_writes_no_file) {
  const fs::path data =
      write("flat.csv", "id,m,err\ns1,a,1\ns1,b,2\ns2,a,3\ns2,b,4\ns3,a,0\ns3,b,1\n");
  const fs::path out = scratch() / "never.json";
  fs::remove(out);
  const Run r = run(data.string() + " --dv err --subject id --within m -o " + out.string());
  BOOST_CHECK_EQUAL(r.code, 1);
  BOOST_CHECK(r.err.find("zero error variance") != std::string::npos);
  BOOST_CHECK(!fs::exists(out));
}

BOOST_AUTO_TEST_CASE(conflicting_flags_exit_2) {
  BOOST_CHECK_EQUAL(run(kDir + "oneway.csv --dv err --subject id --within method --random id").code,
                    2);
  BOOST_CHECK_EQUAL(run(kDir + "oneway.csv --dv err --subject id").code, 2);
  BOOST_CHECK_EQUAL(
      run(kDir + "random3.csv --dv err --fixed method --random kprofile --mixed-model odd").code,
      2);
}

BOOST_AUTO_TEST_CASE(averaged_cells_are_noted_on_stderr) {
  const Run r = run(kDir + "duplicates.csv --dv err --subject id --within method");
  BOOST_REQUIRE_EQUAL(r.code, 0);
  BOOST_CHECK(r.err.find("note: 6 subject x cell entries had several rows") != std::string::npos);
  BOOST_CHECK_EQUAL(nlohmann::json::parse(r.out)["averaged_cells"], 6);
}
