#include "data/trial.hpp"

#include <sstream>

#include "data/error.hpp"

namespace stiffid::data {

int Trial::find(const std::string& name) const {
  for (size_t i = 0; i < names.size(); ++i) {
    if (names[i] == name) return static_cast<int>(i);
  }
  return -1;
}

int Trial::index(const std::string& name) const {
  const int i = find(name);
  if (i < 0) {
    std::ostringstream msg;
    msg << (source.empty() ? std::string("trial") : source) << ": no channel '" << name
        << "' (channels:";
    for (const auto& n : names) msg << ' ' << n;
    msg << ')';
    throw InputError(msg.str());
  }
  return i;
}

Eigen::MatrixXd Trial::columns(const std::vector<std::string>& channel_names) const {
  Eigen::MatrixXd out(samples.rows(), static_cast<Eigen::Index>(channel_names.size()));
  for (size_t j = 0; j < channel_names.size(); ++j)
    out.col(j) = samples.col(index(channel_names[j]));
  return out;
}

namespace {
// Index of the first of `names` when they are consecutive channels in order, else -1.
int consecutive_from(const Trial& trial, const std::vector<std::string>& names) {
  if (names.empty()) return -1;
  const int first = trial.index(names[0]);
  for (std::size_t j = 1; j < names.size(); ++j) {
    if (trial.index(names[j]) != first + static_cast<int>(j)) return -1;
  }
  return first;
}
}  // namespace

Trial::ColumnView::ColumnView(const Trial& trial, const std::vector<std::string>& channel_names)
    : ColumnView(trial, channel_names, consecutive_from(trial, channel_names)) {}

Trial::ColumnView::ColumnView(const Trial& trial, const std::vector<std::string>& channel_names,
                              int first)
    : copy_(first < 0 ? trial.columns(channel_names) : Eigen::MatrixXd()),
      block_(first < 0 ? trial.samples.leftCols(0)
                       : trial.samples.middleCols(
                             first, static_cast<Eigen::Index>(channel_names.size()))) {}

Eigen::VectorXd Trial::time_s() const {
  return Eigen::VectorXd::LinSpaced(sample_count(), 0.0, sample_count() - 1.0) / sample_rate_hz +
         Eigen::VectorXd::Constant(sample_count(), start_time_s);
}

void Trial::add_channel(const std::string& name, const std::string& unit,
                        const Eigen::Ref<const Eigen::VectorXd>& values) {
  if (find(name) >= 0) throw InputError("trial: duplicate channel '" + name + "'");
  if (channel_count() > 0 && values.size() != samples.rows()) {
    throw InputError("trial: channel '" + name + "' has " + std::to_string(values.size()) +
                     " samples, expected " + std::to_string(samples.rows()));
  }
  Eigen::MatrixXd grown(values.size(), samples.cols() + 1);
  if (samples.cols() > 0) grown.leftCols(samples.cols()) = samples;
  grown.col(samples.cols()) = values;
  samples = std::move(grown);
  names.push_back(name);
  units.push_back(unit);
}

void require_samples(const Trial& trial, int required, const std::string& what) {
  if (trial.sample_count() < required) {
    throw InputError((trial.source.empty() ? std::string("trial") : trial.source) + ": " +
                     std::to_string(trial.sample_count()) + " samples, fewer than " + what +
                     " needs (" + std::to_string(required) + ")");
  }
}

}  // namespace stiffid::data
