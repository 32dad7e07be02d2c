// Closed-form checks of stages 2-3 (reassigned spectrogram and ridges): damped exponentials have
// exact STFTs, so frequency, decay rate and amplitude are known at every frame.
#include <boost/test/unit_test.hpp>
#include <cmath>

#include "data/error.hpp"
#include "estimators/reassigned_spectrogram.hpp"
#include "estimators/ridge.hpp"

namespace est = stiffid::estimators;

namespace {

/// x(t) = sum_j a_j exp(alpha_j t) cos(2 pi f_j t + phi_j), t from 0, at fs.
est::TfSignal damped_cosines(double fs, double duration_s, const std::vector<double>& f_hz,
                             const std::vector<double>& alpha, const std::vector<double>& amp,
                             const std::vector<double>& phase) {
  est::TfSignal s;
  s.sample_rate_hz = fs;
  const int n = static_cast<int>(std::lround(duration_s * fs));
  s.real = Eigen::MatrixXd::Zero(n, 1);
  for (int i = 0; i < n; ++i) {
    const double t = i / fs;
    for (size_t j = 0; j < f_hz.size(); ++j) {
      s.real(i, 0) += amp[j] * std::exp(alpha[j] * t) * std::cos(2 * M_PI * f_hz[j] * t + phase[j]);
    }
  }
  return s;
}

}  // namespace

BOOST_AUTO_TEST_CASE(single_decaying_cosine_gives_exact_frequency_decay_and_amplitude) {
  const double f = 6.0, alpha = -1.5, a0 = 0.02, phi = 0.4;
  const est::TfSignal s = damped_cosines(1000.0, 4.0, {f}, {alpha}, {a0}, {phi});
  est::ReassignedSpectrogramOptions o;
  o.window_s = 0.75;
  o.hop_s = 0.01;
  o.max_frequency_hz = 30.0;
  const est::ReassignedSpectrogram sg = est::reassigned_spectrogram(s, o);
  est::RidgeOptions ro;
  ro.modes = 1;
  const est::RidgeResult r = est::track_ridges(sg, ro);
  BOOST_REQUIRE(r.status.ok);
  double worst_f = 0, worst_a = 0, worst_amp = 0;
  for (int m = 0; m < sg.frames(); ++m) {
    const double t = r.time_s(m);
    worst_f = std::max(worst_f, std::abs(r.frequency_hz(m, 0) / f - 1));
    worst_a = std::max(worst_a, std::abs(r.decay_rate_per_s(m, 0) / alpha - 1));
    worst_amp = std::max(worst_amp, std::abs(r.amplitude[0](m, 0) / (a0 * std::exp(alpha * t)) - 1));
  }
  BOOST_TEST_MESSAGE("worst relative errors: f " << worst_f << " alpha " << worst_a << " amp " << worst_amp);
  BOOST_CHECK_LT(worst_f, 1e-3);
  BOOST_CHECK_LT(worst_a, 1e-3);
  BOOST_CHECK_LT(worst_amp, 1e-3);
}
