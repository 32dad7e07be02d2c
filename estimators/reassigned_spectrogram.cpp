#include "estimators/reassigned_spectrogram.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <string>
#include <vector>

#include "data/error.hpp"
#include "data/parallel.hpp"
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
    throw InputError(
        "reassigned spectrogram: the Hilbert transforms must have the shape of the "
        "channels");
  }
  if (!(signal.sample_rate_hz > 0.0)) {
    throw InputError("reassigned spectrogram: sample rate must be positive");
  }
  if (!(options.window_s > 0.0) || !(options.hop_s > 0.0)) {
    throw InputError("reassigned spectrogram: --window-s and --hop-s must be positive, got " +
                     number_text(options.window_s) + " and " + number_text(options.hop_s));
  }
  const double dt = 1.0 / signal.sample_rate_hz;
  const int half = std::max(1, static_cast<int>(std::lround(options.window_s / (2.0 * dt))));
  const int hop = std::max(1, static_cast<int>(std::lround(options.hop_s / dt)));
  const int begin = signal.begin;
  const int end = signal.end < 0 ? samples : signal.end;
  if (begin < 0 || end > samples || end - begin < 2 * half + 1) {
    throw InputError("reassigned spectrogram: the analysed region has " +
                     std::to_string(std::max(0, end - begin)) + " samples (" +
                     number_text(std::max(0, end - begin) * dt) +
                     " s) but one window of --window-s " + number_text(options.window_s) +
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
          ? std::min(nyquist_bin,
                     static_cast<int>(std::floor(options.max_frequency_hz / df + 1e-9)))
          : nyquist_bin;
  if (k_hi < k_lo) {
    throw InputError("reassigned spectrogram: no FFT bin between " +
                     number_text(options.min_frequency_hz) + " and " +
                     number_text(options.max_frequency_hz) + " Hz (bin spacing " + number_text(df) +
                     " Hz)");
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

  // The 3 x parts x C transforms of a frame (window w in {h, th, dh}, part p in {real, imag},
  // channel ch; column (w * parts + p) * C + ch) are made together, for a chunk of frames at a
  // time through one plan made once: the same transforms as one batch of every frame, in cache-
  // sized buffers instead of ~100 MB (968 frames of 512 points at the defaults), whose page faults
  // and zero-filling took half the run. Only the kept bins k_lo..k_hi are stored.
  const int parts = analytic ? 2 : 1;
  const int per_frame = 3 * parts * channels;
  constexpr int kChunkFrames = 16;
  const int chunk_frames = std::min(kChunkFrames, frames);
  std::vector<Eigen::MatrixXcd> band(per_frame);  // filled by the transforms below: not copied
  for (Eigen::MatrixXcd& b : band) b.resize(bins, frames);  // from a prototype, not zeroed
  r.sampled = std::make_shared<const SampledWindow>(options.window, half, dt);
  // Two fixed groups of chunks (one per core of a small machine), each with its own plan and
  // buffers; every frame's transforms are the same whichever group makes them.
  const int chunks = (frames + chunk_frames - 1) / chunk_frames;
  data::parallel_for_groups(
      chunks, std::min(2, chunks), [&](std::size_t, int chunk_begin, int chunk_end) {
        RealFft fft(n_fft, per_frame * chunk_frames);
        for (int index = chunk_begin; index < chunk_end; ++index) {
          const int first = index * chunk_frames;
          const int count = std::min(chunk_frames, frames - first);
          for (int f = 0; f < count; ++f) {
            const int m = first + f;
            const SampledWindow::Cut cut = r.sampled->cut(r.offset_lo(m), r.offset_hi(m));
            const Eigen::VectorXd* windows[3] = {&cut.h, &cut.th, &cut.dh};
            for (int w = 0; w < 3; ++w) {
              for (int p = 0; p < parts; ++p) {
                const Eigen::MatrixXd& x = p == 0 ? signal.real : signal.imag;
                for (int ch = 0; ch < channels; ++ch) {
                  // Offset n goes to FFT index n mod N: the negative offsets wrap to the end, and
                  // the indices between the window's two ends are zero.
                  double* col = fft.input() + static_cast<std::ptrdiff_t>(
                                                  f * per_frame + (w * parts + p) * channels + ch) *
                                                  n_fft;
                  std::fill(col + cut.hi + 1, col + n_fft + std::min(cut.lo, 0), 0.0);
                  if (cut.lo > 0) std::fill(col, col + cut.lo, 0.0);
                  const double* window = windows[w]->data();
                  const double* samples = &x(r.centre(m) + cut.lo, ch);
                  for (int i = 0; i < cut.h.size(); ++i) {
                    const int n = cut.lo + i;
                    col[n < 0 ? n + n_fft : n] = window[i] * samples[i];
                  }
                }
              }
            }
          }
          // Columns of frames past the end of the last chunk hold earlier data: transformed, not
          // read.
          fft.forward_in_place();
          for (int f = 0; f < count; ++f) {
            for (int q = 0; q < per_frame; ++q) {
              const std::complex<double>* spectrum =
                  fft.output() + static_cast<std::ptrdiff_t>(f * per_frame + q) * fft.bins() + k_lo;
              std::copy(spectrum, spectrum + bins, band[q].col(first + f).data());
            }
          }
        }
      });

  auto block = [&](int w, int ch) {
    Eigen::MatrixXcd out = std::move(band[(w * parts + 0) * channels + ch]);
    if (analytic) out += std::complex<double>(0.0, 1.0) * band[(w * parts + 1) * channels + ch];
    return out;
  };
  r.power = Eigen::MatrixXd::Zero(bins, frames);
  r.reassigned_power = Eigen::MatrixXd::Zero(bins, frames);
  for (int ch = 0; ch < channels; ++ch) {
    r.stft.push_back(block(0, ch));
    r.stft_time.push_back(block(1, ch));
    r.stft_derivative.push_back(block(2, ch));
  }
  r.reassigned_time_s.assign(channels, Eigen::MatrixXd(bins, frames));
  r.reassigned_frequency_hz.assign(channels, Eigen::MatrixXd(bins, frames));
  r.decay_rate_per_s.assign(channels, Eigen::MatrixXd(bins, frames));
  // Reassignment of every bin, the channels in parallel; then the power maps summed in channel,
  // frame, bin order (the same sums at any thread count). target: the bin's reassigned cell
  // kk + mm * bins, or -1 (no energy, or outside the map).
  std::vector<Eigen::MatrixXd> power(channels);
  std::vector<std::vector<long>> target(channels);
  data::parallel_for_index(channels, [&](std::size_t c) {
    const Eigen::MatrixXcd& xh = r.stft[c];
    const Eigen::MatrixXcd& xt = r.stft_time[c];
    const Eigen::MatrixXcd& xd = r.stft_derivative[c];
    Eigen::MatrixXd& t_hat = r.reassigned_time_s[c];
    Eigen::MatrixXd& f_hat = r.reassigned_frequency_hz[c];
    Eigen::MatrixXd& a_hat = r.decay_rate_per_s[c];
    power[c] = xh.cwiseAbs2();
    target[c].assign(static_cast<std::size_t>(bins) * frames, -1);
    const double floor = 1e-24 * std::max(1e-300, power[c].maxCoeff());
    for (int m = 0; m < frames; ++m) {
      for (int k = 0; k < bins; ++k) {
        const double p = power[c](k, m);
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
        if (mm >= 0 && mm < frames && kk >= 0 && kk < bins) {
          target[c][static_cast<std::size_t>(m) * bins + k] = kk + mm * bins;
        }
      }
    }
  });
  for (int ch = 0; ch < channels; ++ch) {
    r.power += power[ch];
    double* reassigned = r.reassigned_power.data();
    const double* p = power[ch].data();
    for (std::size_t i = 0; i < target[ch].size(); ++i) {
      if (target[ch][i] >= 0) reassigned[target[ch][i]] += p[i];
    }
  }
  return r;
}

}  // namespace stiffid::estimators
