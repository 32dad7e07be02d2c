// `stiffid anova`: repeated-measures or classical mixed-model ANOVA of a long-format CSV file.

#include <iostream>
#include <memory>

#include "apps/commands.hpp"
#include "data/csv.hpp"
#include "data/error.hpp"
#include "data/output.hpp"
#include "validation/anova.hpp"
#include "validation/anova_report.hpp"

namespace stiffid::apps {
namespace {

struct AnovaArgs {
  std::string data;
  std::string dv;
  std::string subject;
  std::string within, between, pairwise;
  std::string fixed, random;
  std::string mixed_model = "unrestricted";
  std::string output;
};

std::vector<std::string> list(const std::string& text, const std::string& flag) {
  return text.empty() ? std::vector<std::string>{} : data::split_list(text, flag);
}

std::string joined(const std::vector<std::string>& names, const char* sep) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? sep : "") + names[i];
  return out;
}

void run_anova(const AnovaArgs& a) {
  const bool mixed = !a.fixed.empty() || !a.random.empty();
  const bool repeated = !a.subject.empty() || !a.within.empty() || !a.between.empty();
  if (mixed && repeated) {
    throw InputError(
        "--fixed/--random (classical mixed model) cannot be combined with --subject, --within or "
        "--between (repeated measures); to treat subjects as random, give --random " +
        (a.subject.empty() ? std::string("SUBJECT") : a.subject));
  }
  if (!mixed && a.subject.empty()) {
    throw InputError("--subject is required with --within (or give --fixed/--random)");
  }
  if (!mixed && a.within.empty()) {
    throw InputError(
        "--within is required: name the within-subject factors (or give "
        "--fixed/--random for a mixed model)");
  }
  if (mixed && !a.pairwise.empty()) {
    throw InputError("--pairwise works with --subject/--within (paired t-tests on subject means)");
  }
  const data::CsvTable csv = data::read_csv(a.data);
  validation::AnovaResult result;
  std::string title;
  if (mixed) {
    validation::MixedAnovaOptions options;
    options.fixed = list(a.fixed, "--fixed");
    options.random = list(a.random, "--random");
    options.model = a.mixed_model == "restricted" ? validation::MixedModel::restricted
                                                  : validation::MixedModel::unrestricted;
    std::vector<std::string> factors = options.fixed;
    factors.insert(factors.end(), options.random.begin(), options.random.end());
    result =
        validation::mixed_model_anova(validation::long_table_from_csv(csv, a.dv, factors), options);
    title = "Mixed-model ANOVA (" + a.mixed_model + " model, Cornfield-Tukey EMS): " + a.dv +
            " ~ " + joined(factors, " * ") + ", " + std::to_string(result.replicates) +
            " observation(s) per cell";
  } else {
    validation::RepeatedMeasuresOptions options;
    options.subject = a.subject;
    options.within = list(a.within, "--within");
    options.between = list(a.between, "--between");
    options.pairwise = list(a.pairwise, "--pairwise");
    std::vector<std::string> factors{options.subject};
    factors.insert(factors.end(), options.within.begin(), options.within.end());
    factors.insert(factors.end(), options.between.begin(), options.between.end());
    result = validation::repeated_measures_anova(
        validation::long_table_from_csv(csv, a.dv, factors), options);
    std::vector<std::string> all = options.between;
    all.insert(all.end(), options.within.begin(), options.within.end());
    title = "Repeated-measures ANOVA (type III): " + a.dv + " ~ " + joined(all, " * ") + ", " +
            std::to_string(result.subjects) + " subjects";
  }
  const bool json_to_stdout = a.output.empty() || a.output == "-";
  std::ostream& table_stream = json_to_stdout ? std::cerr : std::cout;
  table_stream << validation::format_anova_table(result, title);
  for (const auto& note : result.notes) std::cerr << "stiffid: note: " << note << '\n';
  if (!result.status.ok) throw NumericalFailure(result.status.message);
  data::write_json(a.output, validation::anova_to_json(result));
}

}  // namespace

void add_anova_command(CLI::App& app) {
  auto args = std::make_shared<AnovaArgs>();
  CLI::App* cmd = app.add_subcommand(
      "anova",
      "Repeated-measures ANOVA (as R afex/car: type III, sphericity, GG/HF, eta squared, "
      "pairwise paired t) or classical mixed-model ANOVA with random factors (Cornfield-Tukey "
      "EMS, quasi-F with Satterthwaite df) of a long-format CSV file.\n"
      "  stiffid anova DATA.csv --dv err --subject id --within method,noise [--between group]\n"
      "                [--pairwise method] [-o OUT.json]\n"
      "  stiffid anova DATA.csv --dv err --fixed method,noise --random kprofile,cprofile\n"
      "                [--mixed-model unrestricted|restricted] [-o OUT.json]\n"
      "Output: with -o FILE the APA-like table goes to stdout and the JSON to FILE (written "
      "atomically); without -o (or with -o -) the JSON goes to stdout, clean for parsing, and "
      "the table to stderr. Notes (averaged cells, skipped tests) always go to stderr.\n"
      "Exit codes: 0 ok, 2 bad input (flags, file, design), 1 an effect cannot be tested on "
      "these data (zero error variance, non-positive quasi-F denominator); no JSON is written "
      "then.");
  cmd->add_option("data", args->data, "long-format CSV file (one row per observation)")->required();
  cmd->add_option("--dv", args->dv, "dependent-variable column (numbers)")->required();
  cmd->add_option("--subject", args->subject, "subject column (repeated-measures design)");
  cmd->add_option("--within", args->within, "within-subject factors, comma-separated");
  cmd->add_option("--between", args->between, "between-subject factors, comma-separated");
  cmd->add_option("--pairwise", args->pairwise,
                  "within factors whose levels are compared pairwise (paired t on subject means, "
                  "Holm and Bonferroni)");
  cmd->add_option("--fixed", args->fixed, "fixed factors of a mixed-model design, comma-separated");
  cmd->add_option("--random", args->random,
                  "random factors of a mixed-model design, comma-separated (balanced, fully "
                  "crossed design; no subject column needed)");
  cmd->add_option("--mixed-model", args->mixed_model,
                  "EMS model for random factors: unrestricted (default, as SPSS and lme4) or "
                  "restricted")
      ->check(CLI::IsMember({"unrestricted", "restricted"}));
  cmd->add_option("-o,--output", args->output, "JSON output file ('-' or absent: stdout)");
  cmd->callback([args] { run_anova(*args); });
}

}  // namespace stiffid::apps
