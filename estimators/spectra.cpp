#include "estimators/spectra.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <sstream>

#include "data/error.hpp"
#include "data/parallel.hpp"
#include "estimators/fft.hpp"

namespace stiffid::estimators {
namespace {

// Real samples per batched FFT call (segments x channels x FFT length): small enough that the
// batch, its spectra and the accumulators stay in cache (at 4096-point FFTs of 4 channels, 2
// segments per call ran 1.6x faster than 32), at least one segment, at most 32.
constexpr int kBatchSamples = 32768;
constexpr int kMaxChunkSegments = 32;
// Fixed groups of consecutive segments, summed in parallel and then in group order: the result
// does not depend on the thread count.
constexpr int kSegmentGroups = 8;

// One segment x detrended as scipy.signal.detrend does and multiplied by the window, into out (as
// long as x), in one pass over x for the mean (two for a line) and one to write.
void prepare_segment(const Eigen::Ref<const Eigen::VectorXd>& x, Detrend detrend,
                     const Eigen::VectorXd& window, Eigen::Ref<Eigen::VectorXd> out) {
  if (detrend == Detrend::none) {
    out = x.cwiseProduct(window);
    return;
  }
  const double n = static_cast<double>(x.size());
  const double mean = x.mean();
  if (detrend == Detrend::constant) {
    out = (x.array() - mean).matrix().cwiseProduct(window);
    return;
  }
  // Least-squares line through (k, x_k): with centred abscissae t_k = k - (n - 1) / 2 the slope is
  // sum t (x - mean) / sum t^2 and sum t^2 = n (n^2 - 1) / 12.
  const Eigen::ArrayXd t = Eigen::ArrayXd::LinSpaced(x.size(), -(n - 1) / 2, (n - 1) / 2);
  const double slope = (t * (x.array() - mean)).sum() / (n * (n * n - 1) / 12.0);
  out = ((x.array() - mean) - slope * t).matrix().cwiseProduct(window);
}

}  // namespace

Detrend parse_detrend(const std::string& text, const std::string& flag) {
  if (text == "none") return Detrend::none;
  if (text == "constant") return Detrend::constant;
  if (text == "linear") return Detrend::linear;
  throw InputError(flag + ": bad detrend '" + text + "': expected constant, linear or none");
}

std::string to_string(Detrend detrend) {
  switch (detrend) {
    case Detrend::none:
      return "none";
    case Detrend::constant:
      return "constant";
    case Detrend::linear:
      return "linear";
  }
  return "";
}

int overlap_samples(const WelchOptions& options) {
  return static_cast<int>(std::floor(options.overlap * options.segment_length));
}

int fft_length(const WelchOptions& options) {
  return options.fft_length == 0 ? options.segment_length : options.fft_length;
}

int welch_segment_count(int samples, const WelchOptions& options) {
  const int noverlap = overlap_samples(options);
  if (samples < options.segment_length) return 0;
  return (samples - noverlap) / (options.segment_length - noverlap);
}

void validate(const WelchOptions& options) {
  std::ostringstream msg;
  if (options.segment_length < 2) {
    msg << "Welch segment_length must be >= 2 samples, got " << options.segment_length;
  } else if (options.fft_length != 0 && options.fft_length < options.segment_length) {
    msg << "Welch fft_length must be 0 or >= segment_length (" << options.segment_length
        << "), got " << options.fft_length;
  } else if (!std::isfinite(options.overlap) || options.overlap < 0.0 || options.overlap >= 1.0 ||
             overlap_samples(options) >= options.segment_length) {
    msg << "Welch overlap must be a fraction in [0, 1), got " << options.overlap;
  } else {
    return;
  }
  throw InputError(msg.str());
}

double equivalent_independent_segments(int segments, const WelchOptions& options) {
  return equivalent_independent_segments(segments, options.segment_length, overlap_samples(options),
                                         options.window);
}

double equivalent_independent_segments(int segments, int segment_length, int overlap_samples,
                                       const Window& window) {
  if (segments <= 1) return segments;
  const Eigen::VectorXd w = window.periodic(segment_length);
  const int step = segment_length - overlap_samples;
  const double energy = w.squaredNorm();
  double sum = 0.0;
  for (int m = 1; m < segments && m * step < segment_length; ++m) {
    const int shared = segment_length - m * step;
    const double rho = w.head(shared).dot(w.tail(shared)) / energy;
    sum += (1.0 - static_cast<double>(m) / segments) * rho * rho;
  }
  return segments / (1.0 + 2.0 * sum);
}

CrossSpectra welch_cross_spectra(const Eigen::Ref<const Eigen::MatrixXd>& signals,
                                 double sample_rate_hz, const WelchOptions& options,
                                 const std::string& source) {
  validate(options);
  if (!std::isfinite(sample_rate_hz) || sample_rate_hz <= 0.0) {
    throw InputError(source + ": sample rate must be a positive number of Hz");
  }
  const int samples = static_cast<int>(signals.rows());
  const int channels = static_cast<int>(signals.cols());
  if (samples < options.segment_length) {
    throw InputError(source + ": " + std::to_string(samples) + " samples, fewer than one Welch " +
                     "segment of " + std::to_string(options.segment_length) + " samples needs");
  }
  const int length = options.segment_length;
  const int nfft = fft_length(options);
  const int step = length - overlap_samples(options);
  const int segments = welch_segment_count(samples, options);
  const Eigen::VectorXd window = options.window.periodic(length);

  // Segments go through the FFT in chunks of `chunk` segments of every channel, one batched plan
  // per group; column c * chunk + s holds segment s of channel c, detrended, windowed and zero
  // padded. Chunking bounds memory (a 10-minute 1 kHz trial would otherwise hold ~80 MB of
  // spectra) and keeps the work in cache. Each of up to kSegmentGroups fixed groups of consecutive
  // segments sums its products in segment order, in parallel; the groups are then added in order.
  const int chunk =
      std::clamp(kBatchSamples / (nfft * channels), 1, std::min(segments, kMaxChunkSegments));
  const int groups = std::min(segments, kSegmentGroups);
  const int bins = nfft / 2 + 1;
  const int pairs = channels * (channels + 1) / 2;
  // acc[g] (pairs x bins): column k holds group g's sums over its segments of conj(X_a) X_b at bin
  // k for the pairs a <= b in row-major order (0,0), (0,1), ..., (1,1), ... Bin by bin, each pair
  // sums a chunk's segments in registers into one short column that stays in L1, instead of
  // streaming a whole-spectrum accumulator per pair through memory for every segment; each sum
  // still runs over the segments in order.
  std::vector<Eigen::MatrixXcd> acc(groups);
  data::parallel_for_groups(segments, groups, [&](std::size_t g, int begin, int end) {
    Eigen::MatrixXcd& sum = acc[g];
    sum = Eigen::MatrixXcd::Zero(pairs, bins);
    RealFft fft(nfft, chunk * channels);
    Eigen::MatrixXd batch =
        Eigen::MatrixXd::Zero(nfft, static_cast<Eigen::Index>(chunk) * channels);
    for (int first = begin; first < end; first += chunk) {
      const int count = std::min(chunk, end - first);
      for (int c = 0; c < channels; ++c) {
        for (int s = 0; s < chunk; ++s) {
          auto column = batch.col(static_cast<Eigen::Index>(c) * chunk + s);
          if (s >= count) {  // unused slots of the last chunk
            column.setZero();
            continue;
          }
          prepare_segment(
              signals.col(c).segment(static_cast<Eigen::Index>(first + s) * step, length),
              options.detrend, window, column.head(length));
        }
      }
      const Eigen::MatrixXcd spectra = fft.forward(batch);
      for (int k = 0; k < bins; ++k) {
        std::complex<double>* total = sum.col(k).data();
        const std::complex<double>* bin = spectra.data() + k;  // column c at bin[c * bins]
        for (int a = 0, p = 0; a < channels; ++a) {
          const std::complex<double>* xa = bin + static_cast<Eigen::Index>(a) * chunk * bins;
          for (int b = a; b < channels; ++b, ++p) {
            const std::complex<double>* xb = bin + static_cast<Eigen::Index>(b) * chunk * bins;
            // conj(xa) xb in real arithmetic (std::complex's product adds NaN/Inf recovery),
            // summed over the chunk's segments in order in registers.
            double re = total[p].real(), im = total[p].imag();
            for (int s = 0; s < count; ++s) {
              const std::complex<double> u = xa[s * bins], v = xb[s * bins];
              re += (u.real() * v.real() + u.imag() * v.imag());
              im += (u.real() * v.imag() - u.imag() * v.real());
            }
            total[p] = std::complex<double>(re, im);
          }
        }
      }
    }
  });
  for (int g = 1; g < groups; ++g) acc[0] += acc[g];

  CrossSpectra out;
  out.sample_rate_hz = sample_rate_hz;
  out.segments = segments;
  out.segment_length = length;
  out.fft_length = nfft;
  out.overlap_samples = length - step;
  out.frequency_hz = Eigen::VectorXd::LinSpaced(bins, 0.0, bins - 1.0) * (sample_rate_hz / nfft);
  out.g.assign(bins, Eigen::MatrixXcd(channels, channels));
  // Density scaling of scipy: 1 / (fs sum w^2), mean over segments, one-sided doubling of every
  // bin that has a negative-frequency twin (all but 0 Hz and, for even nfft, fs / 2).
  const double scale = 1.0 / (sample_rate_hz * window.squaredNorm() * segments);
  for (int k = 0; k < bins; ++k) {
    const bool unpaired = k == 0 || (nfft % 2 == 0 && k == bins - 1);
    const double factor = unpaired ? scale : 2.0 * scale;
    for (int a = 0, p = 0; a < channels; ++a) {
      out.g[k](a, a) = acc[0](p++, k).real() * factor;  // exactly real on the diagonal
      for (int b = a + 1; b < channels; ++b) {
        out.g[k](a, b) = acc[0](p++, k) * factor;
        out.g[k](b, a) = std::conj(out.g[k](a, b));
      }
    }
  }
  return out;
}

CrossSpectra welch_cross_spectra(const data::Trial& trial, const std::vector<std::string>& channels,
                                 const WelchOptions& options) {
  validate(options);
  data::require_samples(
      trial, options.segment_length,
      "one Welch segment of " + std::to_string(options.segment_length) + " samples");
  return welch_cross_spectra(trial.column_view(channels).matrix(), trial.sample_rate_hz, options,
                             trial.source.empty() ? "trial" : trial.source);
}

}  // namespace stiffid::estimators
