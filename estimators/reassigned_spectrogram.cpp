#include "estimators/reassigned_spectrogram.hpp"

#include <cmath>
#include <complex>
#include <string>

#include "data/error.hpp"
#include "estimators/fft.hpp"

namespace stiffid::estimators {
namespace {

int next_power_of_two(int n) {
  int p = 1;
  while (p < n) p *= 2;
  return p;
}

}  // namespace

SampledWindow::Cut ReassignedSpectrogram::frame_window(int m) const {
  return sampled->cut(offset_lo(m), offset_hi(m));
}

ReassignedSpectrogram reassigned_spectrogram(const TfSignal& signal,
                                             const ReassignedSpectrogramOptions& options) {
  const int samples = static_cast<int>(signal.real.rows());
  const int channels = static_cast<int>(signal.real.cols());
  const bool analytic = signal.analytic();
  if (analytic && (signal.imag.rows() != samples || signal.imag.cols() != channels)) {
    throw InputError("reassigned spectrogram: the Hilbert transforms must have the shape of the "
                     "channels");
  }
  if (!(signal.sample_rate_hz > 0.0)) {
    throw InputError("reassigned spectrogram: sample rate must be positive");
  }
  if (!(options.window_s > 0.0) || !(options.hop_s > 0.0)) {
    throw InputError("reassigned spectrogram: --window-s and --hop-s must be positive, got " +
                     std::to_string(options.window_s) + " and " + std::to_string(options.hop_s));
  }
  const double dt = 1.0 / signal.sample_rate_hz;
  const int half = std::max(1, static_cast<int>(std::lround(options.window_s / (2.0 * dt))));
  const int hop = std::max(1, static_cast<int>(std::lround(options.hop_s / dt)));
  const int begin = signal.begin;
  const int end = signal.end < 0 ? samples : signal.end;
  if (begin < 0 || end > samples || end - begin < 2 * half + 1) {
    throw InputError("reassigned spectrogram: the analysed region has " +
                     std::to_string(std::max(0, end - begin)) + " samples (" +
                     std::to_string(std::max(0, end - begin) * dt) +
                     " s) but one window of --window-s " + std::to_string(options.window_s) +
                     " s needs " + std::to_string(2 * half + 1) + " samples");
  }
  const int n_fft = options.fft_size > 0 ? options.fft_size : next_power_of_two(2 * half + 1);
  if (n_fft < 2 * half + 1) {
    throw InputError("reassigned spectrogram: FFT size " + std::to_string(n_fft) +
                     " is shorter than the window (" + std::to_string(2 * half + 1) + " samples)");
  }
  const double df = signal.sample_rate_hz / n_fft;
  const int nyquist_bin = n_fft / 2;
  const int k_lo = std::max(0, static_cast<int>(std::ceil(options.min_frequency_hz / df - 1e-9)));
  const int k_hi =
      options.max_frequency_hz > 0.0
          ? std::min(nyquist_bin, static_cast<int>(std::floor(options.max_frequency_hz / df + 1e-9)))
          : nyquist_bin;
  if (k_hi < k_lo) {
    throw InputError("reassigned spectrogram: no FFT bin between " +
                     std::to_string(options.min_frequency_hz) + " and " +
                     std::to_string(options.max_frequency_hz) + " Hz (bin spacing " +
                     std::to_string(df) + " Hz)");
  }

  ReassignedSpectrogram r;
  r.sample_rate_hz = signal.sample_rate_hz;
  r.hop_samples = hop;
  r.hop_s = hop * dt;
  r.fft_size = n_fft;
  r.first_bin = k_lo;
  r.window = options.window;
  r.half_length = half;
  r.analytic = analytic;
  const int frames = (end - 1 - begin) / hop + 1;
  const int bins = k_hi - k_lo + 1;
  r.time_s.resize(frames);
  r.centre.resize(frames);
  r.offset_lo.resize(frames);
  r.offset_hi.resize(frames);
  for (int m = 0; m < frames; ++m) {
    const int c = begin + m * hop;
    r.centre(m) = c;
    r.time_s(m) = signal.start_time_s + c * dt;
    r.offset_lo(m) = std::max(-half, begin - c);
    r.offset_hi(m) = std::min(half, end - 1 - c);
  }
  r.frequency_hz = Eigen::VectorXd::LinSpaced(bins, k_lo * df, k_hi * df);

  // One batch: column ((w * parts + p) * C + ch) * T + m, w in {h, th, dh}, p in {real, imag}.
  const int parts = analytic ? 2 : 1;
  const int batch = 3 * parts * channels * frames;
  Eigen::MatrixXd frames_in = Eigen::MatrixXd::Zero(n_fft, batch);
  r.sampled = std::make_shared<const SampledWindow>(options.window, half, dt);
  for (int m = 0; m < frames; ++m) {
    const SampledWindow::Cut cut = r.sampled->cut(r.offset_lo(m), r.offset_hi(m));
    const Eigen::VectorXd* windows[3] = {&cut.h, &cut.th, &cut.dh};
    for (int w = 0; w < 3; ++w) {
      for (int p = 0; p < parts; ++p) {
        const Eigen::MatrixXd& x = p == 0 ? signal.real : signal.imag;
        for (int ch = 0; ch < channels; ++ch) {
          double* col = frames_in.col(((w * parts + p) * channels + ch) * frames + m).data();
          for (int i = 0; i < cut.h.size(); ++i) {
            const int n = cut.lo + i;
            col[(n + n_fft) % n_fft] = (*windows[w])(i) * x(r.centre(m) + n, ch);
          }
        }
      }
    }
  }
  RealFft fft(n_fft, batch);
  const Eigen::MatrixXcd spectra = fft.forward(frames_in);
  frames_in.resize(0, 0);

  auto block = [&](int w, int ch) {
    Eigen::MatrixXcd out =
        spectra.block(k_lo, ((w * parts + 0) * channels + ch) * frames, bins, frames);
    if (analytic) {
      out += std::complex<double>(0.0, 1.0) *
             spectra.block(k_lo, ((w * parts + 1) * channels + ch) * frames, bins, frames);
    }
    return out;
  };
  r.power = Eigen::MatrixXd::Zero(bins, frames);
  r.reassigned_power = Eigen::MatrixXd::Zero(bins, frames);
  for (int ch = 0; ch < channels; ++ch) {
    r.stft.push_back(block(0, ch));
    r.stft_time.push_back(block(1, ch));
    r.stft_derivative.push_back(block(2, ch));
    const Eigen::MatrixXcd& xh = r.stft.back();
    const Eigen::MatrixXcd& xt = r.stft_time.back();
    const Eigen::MatrixXcd& xd = r.stft_derivative.back();
    Eigen::MatrixXd t_hat(bins, frames), f_hat(bins, frames), a_hat(bins, frames);
    const double floor = 1e-24 * std::max(1e-300, xh.cwiseAbs2().maxCoeff());
    for (int m = 0; m < frames; ++m) {
      for (int k = 0; k < bins; ++k) {
        const double p = std::norm(xh(k, m));
        r.power(k, m) += p;
        if (p <= floor) {  // no energy: nothing to reassign
          t_hat(k, m) = r.time_s(m);
          f_hat(k, m) = r.frequency_hz(k);
          a_hat(k, m) = 0.0;
          continue;
        }
        const std::complex<double> rd = xd(k, m) / xh(k, m);
        t_hat(k, m) = r.time_s(m) + std::real(xt(k, m) / xh(k, m));
        f_hat(k, m) = r.frequency_hz(k) - std::imag(rd) / (2.0 * M_PI);
        a_hat(k, m) = -std::real(rd);
        const long mm = std::lround((t_hat(k, m) - r.time_s(0)) / r.hop_s);
        const long kk = std::lround((f_hat(k, m) - r.frequency_hz(0)) / df);
        if (mm >= 0 && mm < frames && kk >= 0 && kk < bins) r.reassigned_power(kk, mm) += p;
      }
    }
    r.reassigned_time_s.push_back(std::move(t_hat));
    r.reassigned_frequency_hz.push_back(std::move(f_hat));
    r.decay_rate_per_s.push_back(std::move(a_hat));
  }
  return r;
}

}  // namespace stiffid::estimators
