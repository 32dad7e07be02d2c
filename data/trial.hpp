#pragma once
// A trial: named channels of doubles sampled at a uniform rate, with a unit per channel.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace stiffid::data {

struct Trial {
  double sample_rate_hz = 0.0;     ///< uniform sampling rate, Hz
  double start_time_s = 0.0;       ///< time of the first sample, s
  std::vector<std::string> names;  ///< [C] channel names, unique
  std::vector<std::string> units;  ///< [C] channel units ("" when unknown), e.g. "N", "m", "rad"
  Eigen::MatrixXd samples;         ///< (S x C) one column per channel
  std::string source;              ///< where the trial came from (file path), for messages

  int sample_count() const { return static_cast<int>(samples.rows()); }
  int channel_count() const { return static_cast<int>(samples.cols()); }
  double step_s() const { return 1.0 / sample_rate_hz; }
  double duration_s() const { return sample_count() / sample_rate_hz; }

  /// Index of a channel; -1 when absent.
  int find(const std::string& name) const;
  /// Index of a channel; throws InputError naming the trial's source and the channels it has.
  int index(const std::string& name) const;
  /// Copy of the named channels as columns (S x names.size()); throws InputError on a missing one.
  Eigen::MatrixXd columns(const std::vector<std::string>& channel_names) const;
  /// The named channels as an (S x names.size()) matrix view: the trial's own columns when the
  /// names are consecutive channels in order (no copy of the record), else a copy held by the
  /// view. Valid while the trial lives. Throws InputError on a missing channel.
  class ColumnView {
   public:
    ColumnView(const Trial& trial, const std::vector<std::string>& channel_names);
    Eigen::Ref<const Eigen::MatrixXd> matrix() const {
      return copy_.size() > 0 ? Eigen::Ref<const Eigen::MatrixXd>(copy_) : block_;
    }

   private:
    ColumnView(const Trial& trial, const std::vector<std::string>& channel_names, int first);
    Eigen::MatrixXd copy_;
    Eigen::Ref<const Eigen::MatrixXd> block_;
  };
  ColumnView column_view(const std::vector<std::string>& channel_names) const {
    return ColumnView(*this, channel_names);
  }
  /// Sample times, s (S).
  Eigen::VectorXd time_s() const;
  /// Appends a channel; throws InputError on a duplicate name or a length mismatch.
  void add_channel(const std::string& name, const std::string& unit,
                   const Eigen::Ref<const Eigen::VectorXd>& values);
};

/// Throws InputError when the trial has fewer than `required` samples, naming the trial's source
/// and what needs them (e.g. "one Welch segment of 256 samples").
void require_samples(const Trial& trial, int required, const std::string& what);

}  // namespace stiffid::data
