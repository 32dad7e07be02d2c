#include "estimators/ridge.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "data/error.hpp"
#include "data/parallel.hpp"
#include "estimators/savitzky_golay.hpp"

namespace stiffid::estimators {
namespace {

using cd = std::complex<double>;
constexpr cd kI(0.0, 1.0);

/// Joint DP; returns (T x n) bins, indices into the spectrogram's bins.
Eigen::MatrixXi dp_ridges(const Eigen::MatrixXd& map, int band_lo, int band_hi, int modes,
                          double penalty_per_bin, int max_jump_bins) {
  const int frames = static_cast<int>(map.cols());
  const int width = band_hi - band_lo + 1;
  // Dense mixed-radix index of every strictly increasing tuple of band bins.
  long dense = 1;
  for (int j = 0; j < modes; ++j) dense *= width;
  if (dense > 20'000'000) {
    throw InputError("ridge tracking: " + std::to_string(width) + " bins in the band for " +
                     std::to_string(modes) + " modes is too many states; narrow the band");
  }
  std::vector<int> index(static_cast<size_t>(dense), -1);
  std::vector<int> tuples;  // state s -> tuples[s * modes + j], ascending
  std::vector<int> t(modes);
  for (int j = 0; j < modes; ++j) t[j] = j;
  if (modes <= width) {
    while (true) {
      long key = 0;
      for (int j = 0; j < modes; ++j) key = key * width + t[j];
      index[key] = static_cast<int>(tuples.size() / modes);
      tuples.insert(tuples.end(), t.begin(), t.end());
      int j = modes - 1;
      while (j >= 0 && t[j] == width - modes + j) --j;
      if (j < 0) break;
      ++t[j];
      for (int i = j + 1; i < modes; ++i) t[i] = t[i - 1] + 1;
    }
  }
  const int states = static_cast<int>(tuples.size() / modes);
  auto local = [&](int s, int m) {
    double v = 0.0;
    for (int j = 0; j < modes; ++j) v += map(band_lo + tuples[s * modes + j], m);
    return v;
  };
  // Offsets in [-J, J]^n with their penalties.
  std::vector<std::vector<int>> offsets;
  std::vector<double> offset_cost;
  const int span = 2 * max_jump_bins + 1;
  long combos = 1;
  for (int j = 0; j < modes; ++j) combos *= span;
  for (long c = 0; c < combos; ++c) {
    std::vector<int> d(modes);
    long r = c;
    double cost = 0.0;
    for (int j = 0; j < modes; ++j) {
      d[j] = static_cast<int>(r % span) - max_jump_bins;
      r /= span;
      cost += penalty_per_bin * std::abs(d[j]);
    }
    offsets.push_back(d);
    offset_cost.push_back(cost);
  }
  // The predecessors of every state and their jump costs do not depend on the frame: listed once
  // (state s: predecessor[first[s] .. first[s + 1])), in the offsets' order.
  std::vector<int> first(states + 1, 0), predecessor;
  std::vector<double> jump_cost;
  for (int s = 0; s < states; ++s) {
    for (size_t o = 0; o < offsets.size(); ++o) {
      long key = 0;
      bool ok = true;
      for (int j = 0; j < modes; ++j) {
        const int b = tuples[s * modes + j] - offsets[o][j];
        if (b < 0 || b >= width) {
          ok = false;
          break;
        }
        key = key * width + b;
      }
      if (!ok || index[key] < 0) continue;
      predecessor.push_back(index[key]);
      jump_cost.push_back(offset_cost[o]);
    }
    first[s + 1] = static_cast<int>(predecessor.size());
  }
  std::vector<double> score(states), next(states);
  Eigen::MatrixXi back(states, frames);
  for (int s = 0; s < states; ++s) score[s] = local(s, 0);
  for (int m = 1; m < frames; ++m) {
    for (int s = 0; s < states; ++s) {
      double best = -std::numeric_limits<double>::infinity();
      int arg = s;
      for (int q = first[s]; q < first[s + 1]; ++q) {
        const double v = score[predecessor[q]] - jump_cost[q];
        if (v > best) {
          best = v;
          arg = predecessor[q];
        }
      }
      next[s] = best + local(s, m);
      back(s, m) = arg;
    }
    std::swap(score, next);
  }
  int s = static_cast<int>(std::max_element(score.begin(), score.end()) - score.begin());
  Eigen::MatrixXi path(frames, modes);
  for (int m = frames - 1; m >= 0; --m) {
    for (int j = 0; j < modes; ++j) path(m, j) = band_lo + tuples[s * modes + j];
    if (m > 0) s = back(s, m);
  }
  return path;
}

/// Solves Wd(s) / W(s) = r for s near -r (Newton on Wd - r W).
bool solve_reassignment(const SampledWindow::Cut& cut, double dt, cd r, cd& s) {
  s = -r;
  for (int it = 0; it < 8; ++it) {
    const auto w = SampledWindow::transform(cut, dt, s);
    const cd f = w.wd - r * w.w;
    const cd fp = w.wdt - r * w.wt;
    if (std::abs(fp) == 0.0) return false;
    const cd step = f / fp;
    s -= step;
    if (!std::isfinite(s.real()) || !std::isfinite(s.imag())) return false;
    if (std::abs(step) <= 1e-13 * (1.0 + std::abs(s))) break;
  }
  return true;
}

struct FrameContext {
  const ReassignedSpectrogram& sg;
  const RidgeOptions& options;
  int n;
  int channels;
  bool real_signal;
};

/// lambda_j (n) and complex amplitudes c_jk (n x C) of one frame: channel k is
/// sum_j c_jk exp(lambda_j u) (+ conj(c_jk) exp(conj(lambda_j) u) for real signals).
struct FrameFit {
  std::vector<cd> lambda;
  std::vector<cd> chirp;  ///< d lambda_j / dt at the frame centre, 1/s^2 (RidgeOptions::fit_chirp)
  Eigen::MatrixXcd coef;
  bool ok = false;
  /// Window transforms of the last evaluation (gauss_newton) at these lambdas, window cut and
  /// bins, [bin][mode][image]: a neighbouring frame started from this fit has the same lambdas,
  /// and for interior frames the same cut and usually the same bins, so it reuses them.
  std::vector<SampledWindow::Transform> transforms;
  int transforms_lo = 0, transforms_hi = -1;
  std::vector<int> transforms_bins;
  bool degenerate = false;  ///< not n distinct modes (degenerate_fit)
  bool misfit = false;      ///< the chirped frame model misses the data (hold_chirp_rates)
  /// Gauss-Newton's final sum of squared residuals over the sum of squares of the data it fitted
  /// (X_h and the weighted X_dh at the fit bins): the part of the frame the model misses.
  double relative_cost = std::numeric_limits<double>::infinity();
  double cost = std::numeric_limits<double>::infinity();  ///< the final sum of squares
  double noise_per_row = 0.0;  ///< expected noise variance of one real residual (0: unknown)
};

/// Moves a fit by shift_s along its model: each mode's complex amplitudes by
/// exp(lambda_j shift + g_j shift^2 / 2) and lambda_j by g_j shift (g_j = chirp[j], 0 when the fit
/// has none), so that it describes the frame centred shift_s later.
void move_fit(FrameFit& fit, double shift_s) {
  for (std::size_t j = 0; j < fit.lambda.size(); ++j) {
    const cd g = fit.chirp.empty() ? cd(0.0) : fit.chirp[j];
    fit.coef.row(static_cast<Eigen::Index>(j)) *=
        std::exp(fit.lambda[j] * shift_s + 0.5 * g * shift_s * shift_s);
    fit.lambda[j] += g * shift_s;
  }
}

/// Whether frame m's window is long enough for pass 1 to fit chirp rates (at least
/// chirp_min_window_fraction of the full length; in windows cut short at the ends of the free
/// response they are ill-determined).
bool chirp_window(const ReassignedSpectrogram& sg, const RidgeOptions& options, int m) {
  return sg.offset_hi(m) - sg.offset_lo(m) >=
         options.chirp_min_window_fraction * 2 * sg.half_length;
}

/// Least-squares complex amplitudes for given lambdas on `bins` (X_h only).
bool fit_amplitudes(const FrameContext& ctx, int m, const SampledWindow::Cut& cut,
                    const std::vector<int>& bins, FrameFit& fit) {
  const ReassignedSpectrogram& sg = ctx.sg;
  const double dt = 1.0 / sg.sample_rate_hz;
  const int rows = static_cast<int>(bins.size());
  const int n = ctx.n;
  Eigen::MatrixXd a(2 * rows, 2 * n), b(2 * rows, ctx.channels);
  for (int i = 0; i < rows; ++i) {
    const double nu = 2.0 * M_PI * sg.frequency_hz(bins[i]);
    for (int j = 0; j < n; ++j) {
      const cd w1 = SampledWindow::transform(cut, dt, fit.lambda[j] - kI * nu).w;
      const cd w2 = ctx.real_signal
                        ? SampledWindow::transform(cut, dt, std::conj(fit.lambda[j]) - kI * nu).w
                        : cd(0.0);
      const cd col_re = w1 + w2, col_im = kI * (w1 - w2);
      a(2 * i, 2 * j) = col_re.real();
      a(2 * i + 1, 2 * j) = col_re.imag();
      a(2 * i, 2 * j + 1) = col_im.real();
      a(2 * i + 1, 2 * j + 1) = col_im.imag();
    }
    for (int c = 0; c < ctx.channels; ++c) {
      b(2 * i, c) = sg.stft[c](bins[i], m).real();
      b(2 * i + 1, c) = sg.stft[c](bins[i], m).imag();
    }
  }
  const Eigen::MatrixXd sol = a.colPivHouseholderQr().solve(b);
  fit.coef.resize(n, ctx.channels);
  for (int j = 0; j < n; ++j) {
    for (int c = 0; c < ctx.channels; ++c) fit.coef(j, c) = cd(sol(2 * j, c), sol(2 * j + 1, c));
  }
  return fit.coef.allFinite();
}

/// Starting values: channel-weighted reassignment at each ridge bin, then rounds of interference
/// cancellation (subtract the other components from X_h and X_dh, reassign again).
FrameFit initial_fit(const FrameContext& ctx, int m, const std::vector<int>& ridge) {
  const ReassignedSpectrogram& sg = ctx.sg;
  const double dt = 1.0 / sg.sample_rate_hz;
  const SampledWindow::Cut cut = sg.frame_window(m);
  const int n = ctx.n, channels = ctx.channels;
  FrameFit fit;
  fit.lambda.resize(n);
  auto nu = [&](int k) { return 2.0 * M_PI * sg.frequency_hz(k); };
  auto reassign = [&](int j, const std::vector<cd>& xh, const std::vector<cd>& xd, cd& out) {
    cd num = 0.0;
    double den = 0.0;
    for (int c = 0; c < channels; ++c) {
      num += std::conj(xh[c]) * xd[c];
      den += std::norm(xh[c]);
    }
    cd s;
    if (!(den > 0.0) || !solve_reassignment(cut, dt, num / den, s)) return false;
    out = s + kI * nu(ridge[j]);
    return true;
  };
  for (int j = 0; j < n; ++j) {
    std::vector<cd> xh(channels), xd(channels);
    for (int c = 0; c < channels; ++c) {
      xh[c] = sg.stft[c](ridge[j], m);
      xd[c] = sg.stft_derivative[c](ridge[j], m);
    }
    if (!reassign(j, xh, xd, fit.lambda[j])) return fit;
  }
  for (int it = 0; it < ctx.options.refine_iterations; ++it) {
    if (!fit_amplitudes(ctx, m, cut, ridge, fit)) return fit;
    std::vector<cd> next = fit.lambda;
    for (int j = 0; j < n; ++j) {
      const int k = ridge[j];
      std::vector<cd> xh(channels), xd(channels);
      for (int c = 0; c < channels; ++c) {
        xh[c] = sg.stft[c](k, m);
        xd[c] = sg.stft_derivative[c](k, m);
      }
      for (int i = 0; i < n; ++i) {
        for (int image = 0; image < (ctx.real_signal ? 2 : 1); ++image) {
          if (i == j && image == 0) continue;  // the component being estimated
          const cd mu = image == 0 ? fit.lambda[i] : std::conj(fit.lambda[i]);
          const auto w = SampledWindow::transform(cut, dt, mu - kI * nu(k));
          for (int c = 0; c < channels; ++c) {
            const cd cc = image == 0 ? fit.coef(i, c) : std::conj(fit.coef(i, c));
            xh[c] -= cc * w.w;
            xd[c] -= cc * w.wd;
          }
        }
      }
      cd updated;
      if (!reassign(j, xh, xd, updated)) return fit;
      // Under-relaxed: the plain fixed point oscillates when components overlap strongly.
      next[j] = fit.lambda[j] + ctx.options.relaxation * (updated - fit.lambda[j]);
    }
    fit.lambda = next;
  }
  fit.ok = fit_amplitudes(ctx, m, cut, ridge, fit);
  return fit;
}

/// The spectrogram bin nearest frequency_hz (clamped to the bins kept).
int nearest_bin(const ReassignedSpectrogram& sg, double frequency_hz) {
  const double df = sg.sample_rate_hz / sg.fft_size;
  return std::clamp(static_cast<int>(std::lround(frequency_hz / df)) - sg.first_bin, 0,
                    sg.bins() - 1);
}

/// The frame model's chirp rates g_j = d lambda_j / dt: zero (a stationary fit), fitted with the
/// other unknowns, or held at FrameFit::chirp.
enum class Chirp { none, fitted, held };

/// Gauss-Newton on the frame's exact model of X_h and X_dh at the fit bins (the bins `centres`
/// +- fit_half_width_bins) in all channels: unknowns Re/Im lambda_j, Re/Im c_jk and, with
/// Chirp::fitted, Re/Im g_j, derivatives from the window transforms (dW/ds = Wt, dWd/ds = Wdt,
/// dW/dg = Wtt / 2, dWd/dg = Wdtt / 2). X_dh is weighted by T / (2 pi) to match the scale of X_h.
/// Leaves the final sum of squares in `fit` and, with fit_chirp, its part of the data and the
/// noise per residual.
bool gauss_newton(const FrameContext& ctx, int m, const std::vector<int>& centres, FrameFit& fit,
                  Chirp chirp_mode) {
  const bool chirp = chirp_mode == Chirp::fitted;  // chirp rates among the unknowns
  const bool chirped = chirp_mode != Chirp::none;  // transforms with the chirp rates
  const ReassignedSpectrogram& sg = ctx.sg;
  const double dt = 1.0 / sg.sample_rate_hz;
  const SampledWindow::Cut cut = sg.frame_window(m);
  const int n = ctx.n, channels = ctx.channels;
  std::vector<int> bins;
  for (int j = 0; j < n; ++j) {
    for (int d = -ctx.options.fit_half_width_bins; d <= ctx.options.fit_half_width_bins; ++d) {
      const int k = centres[j] + d;
      if (k >= 0 && k < sg.bins()) bins.push_back(k);
    }
  }
  std::sort(bins.begin(), bins.end());
  bins.erase(std::unique(bins.begin(), bins.end()), bins.end());
  const int nb = static_cast<int>(bins.size());
  const double wd_weight = (cut.hi - cut.lo) * dt / (2.0 * M_PI);
  const int nl = chirp ? 4 : 2;  // real unknowns per mode: lambda (and its chirp rate)
  if (static_cast<int>(fit.chirp.size()) != n || !chirped) fit.chirp.assign(n, cd(0.0));
  const double half_window_s = 0.5 * (cut.hi - cut.lo) * dt;
  const int unknowns = nl * n + 2 * n * channels;
  const int rows = 2 * 2 * nb * channels;  // (h, dh) x bins x channels, real and imaginary
  const int images = ctx.real_signal ? 2 : 1;

  // The chirped windows of each mode: once for held chirp rates, at every evaluation for fitted.
  std::vector<SampledWindow::ChirpedCut> chirped_cuts(chirped ? n : 0);
  if (chirp_mode == Chirp::held) {
    for (int j = 0; j < n; ++j) {
      chirped_cuts[j] = SampledWindow::chirped(cut, dt, fit.chirp[j], false);
    }
  }
  // Fills f.transforms for f.lambda (unless they are already those of this cut and these bins),
  // then the residual and the Jacobian.
  auto evaluate = [&](FrameFit& f, Eigen::VectorXd& residual, Eigen::MatrixXd* jac,
                      bool transforms_current) {
    if (chirped || !transforms_current || f.transforms_lo != cut.lo || f.transforms_hi != cut.hi ||
        f.transforms_bins != bins) {
      f.transforms.resize(nb * n * images);
      if (chirp) {  // the chirp rates are unknowns: their windows change with every step
        for (int j = 0; j < n; ++j) {
          chirped_cuts[j] = SampledWindow::chirped(cut, dt, f.chirp[j], true);
        }
      }
      for (int i = 0; i < nb; ++i) {
        const double nu = 2.0 * M_PI * sg.frequency_hz(bins[i]);
        for (int j = 0; j < n; ++j) {
          auto* t = &f.transforms[(i * n + j) * images];
          if (chirped) {
            t[0] = SampledWindow::transform(chirped_cuts[j], dt, f.lambda[j] - kI * nu);
            if (images == 2) {  // the image's windows are those of conj(g)
              t[1] = SampledWindow::transform(chirped_cuts[j], dt, std::conj(f.lambda[j]) - kI * nu,
                                              true);
            }
            continue;
          }
          t[0] = SampledWindow::transform(cut, dt, f.lambda[j] - kI * nu);
          if (images == 2) {
            t[1] = SampledWindow::transform(cut, dt, std::conj(f.lambda[j]) - kI * nu);
          }
        }
      }
      f.transforms_lo = cut.lo;
      f.transforms_hi = cut.hi;
      f.transforms_bins = bins;
    }
    residual.resize(rows);
    if (jac) jac->setZero(rows, unknowns);
    for (int i = 0; i < nb; ++i) {
      const SampledWindow::Transform* t = &f.transforms[i * n * images];
      for (int c = 0; c < channels; ++c) {
        cd model_h = 0.0, model_d = 0.0;
        const int row_h = 4 * (i * channels + c), row_d = row_h + 2;
        for (int j = 0; j < n; ++j) {
          const cd cc = f.coef(j, c);
          const auto& a = t[j * images];
          model_h += cc * a.w;
          model_d += cc * a.wd;
          cd dh_dp = cc * a.wt, dd_dp = cc * a.wdt;  // d/d Re lambda
          cd dh_dq = kI * cc * a.wt, dd_dq = kI * cc * a.wdt;
          cd dh_dre = a.w, dd_dre = a.wd, dh_dim = kI * a.w, dd_dim = kI * a.wd;
          cd dh_dgp = 0.5 * cc * a.wtt, dd_dgp = 0.5 * cc * a.wdtt;  // d/d Re g
          cd dh_dgq = kI * dh_dgp, dd_dgq = kI * dd_dgp;
          if (images == 2) {
            const auto& b = t[j * images + 1];
            const cd cb = std::conj(cc);
            model_h += cb * b.w;
            model_d += cb * b.wd;
            dh_dp += cb * b.wt;
            dd_dp += cb * b.wdt;
            dh_dq -= kI * cb * b.wt;
            dd_dq -= kI * cb * b.wdt;
            dh_dre += b.w;
            dd_dre += b.wd;
            dh_dim -= kI * b.w;
            dd_dim -= kI * b.wd;
            dh_dgp += 0.5 * cb * b.wtt;
            dd_dgp += 0.5 * cb * b.wdtt;
            dh_dgq -= 0.5 * kI * cb * b.wtt;
            dd_dgq -= 0.5 * kI * cb * b.wdtt;
          }
          if (jac) {
            const int cols[6] = {nl * j,
                                 nl * j + 1,
                                 nl * n + 2 * (j * channels + c),
                                 nl * n + 2 * (j * channels + c) + 1,
                                 nl * j + 2,
                                 nl * j + 3};
            const cd dh[6] = {dh_dp, dh_dq, dh_dre, dh_dim, dh_dgp, dh_dgq};
            const cd dd[6] = {dd_dp, dd_dq, dd_dre, dd_dim, dd_dgp, dd_dgq};
            for (int q = 0; q < (chirp ? 6 : 4); ++q) {
              (*jac)(row_h, cols[q]) += dh[q].real();
              (*jac)(row_h + 1, cols[q]) += dh[q].imag();
              (*jac)(row_d, cols[q]) += wd_weight * dd[q].real();
              (*jac)(row_d + 1, cols[q]) += wd_weight * dd[q].imag();
            }
          }
        }
        const cd rh = sg.stft[c](bins[i], m) - model_h;
        const cd rd = wd_weight * (sg.stft_derivative[c](bins[i], m) - model_d);
        residual(row_h) = rh.real();
        residual(row_h + 1) = rh.imag();
        residual(row_d) = rd.real();
        residual(row_d + 1) = rd.imag();
      }
    }
  };
  Eigen::VectorXd residual, trial_residual;
  Eigen::MatrixXd jac, trial_jac;
  // A warm start keeps its neighbour's lambdas: their transforms are current.
  evaluate(fit, residual, &jac, !fit.transforms.empty());
  double cost = residual.squaredNorm();
  for (int it = 0; it < 10; ++it) {
    if (!std::isfinite(cost)) return false;
    const Eigen::VectorXd step = jac.colPivHouseholderQr().solve(residual);
    if (!step.allFinite()) return false;
    double scale = 1.0;
    bool improved = false;
    FrameFit trial = fit;
    double trial_cost = cost;
    for (int half = 0; half < 6 && !improved; ++half, scale *= 0.5) {
      for (int j = 0; j < n; ++j) {
        trial.lambda[j] = fit.lambda[j] + scale * cd(step(nl * j), step(nl * j + 1));
        if (chirp) trial.chirp[j] = fit.chirp[j] + scale * cd(step(nl * j + 2), step(nl * j + 3));
        for (int c = 0; c < channels; ++c) {
          const int col = nl * n + 2 * (j * channels + c);
          trial.coef(j, c) = fit.coef(j, c) + scale * cd(step(col), step(col + 1));
        }
      }
      evaluate(trial, trial_residual, &trial_jac, false);  // the Jacobian is reused when accepted
      trial_cost = trial_residual.squaredNorm();
      improved = trial_cost <= cost;
    }
    if (!improved) break;  // at the minimum to round-off
    // The accepted step, relative to the parameters: converged below 1e-6. Noise-free, Gauss-
    // Newton converges quadratically (the next step would be ~1e-12: results within 1e-13 of a
    // fit run to round-off); with noise linearly, and the frame parameters stay within ~1e-5 of
    // it (20 dB sigmoid trial: K within 1.1e-6, C 7.8e-6 relative), far below their noise.
    double relative_step = 0.0;
    for (int j = 0; j < n; ++j) {
      const double lambda_step = (std::abs(trial.lambda[j] - fit.lambda[j]) +
                                  half_window_s * std::abs(trial.chirp[j] - fit.chirp[j])) /
                                 std::abs(fit.lambda[j]);
      const double size = fit.coef.row(j).cwiseAbs().maxCoeff();
      const double coef_step = (trial.coef.row(j) - fit.coef.row(j)).cwiseAbs().maxCoeff() / size;
      relative_step = std::max({relative_step, lambda_step, coef_step});
    }
    fit = trial;
    std::swap(residual, trial_residual);
    std::swap(jac, trial_jac);
    const double previous = cost;
    cost = trial_cost;
    if (previous - cost <= 1e-14 * previous || relative_step <= 1e-6) break;
  }
  fit.cost = cost;
  if (!ctx.options.fit_chirp) return std::isfinite(cost);  // the rest serves the chirped fits
  double data = 0.0;
  for (int i = 0; i < nb; ++i) {
    for (int c = 0; c < channels; ++c) {
      data += std::norm(sg.stft[c](bins[i], m)) +
              wd_weight * wd_weight * std::norm(sg.stft_derivative[c](bins[i], m));
    }
  }
  fit.relative_cost = data > 0.0 ? cost / data : std::numeric_limits<double>::infinity();
  fit.noise_per_row = 0.0;
  if (ctx.options.noise_covariance.rows() == channels) {
    // White noise of variance S_cc per sample: E|X_h|^2 = S_cc sum h^2, E|X_dh|^2 = S_cc sum dh^2
    // (weighted by wd_weight^2), half of each in the real and the imaginary row.
    const double trace = ctx.options.noise_covariance.trace();
    fit.noise_per_row = trace *
                        (cut.h.squaredNorm() + wd_weight * wd_weight * cut.dh.squaredNorm()) /
                        (4.0 * channels);
  }
  return std::isfinite(cost);
}

/// A converged fit that does not describe n distinct modes (the frame is invalid for every mode,
/// and a chain started from it would stay in it):
/// - its frequencies are out of the ridges' order (the ridges never cross, nor do the modes of the
///   free response: a mode's fit has jumped onto or past another mode's), or
/// - some mode's own part of X_h at the fit bins, in all channels, has more than
///   max_mode_to_data_db above the energy of X_h there. Each mode of a sum of damped oscillations
///   has about the energy of the sum at most, plus the noise's and what two modes within one main
///   lobe take from each other (up to 4 dB in the simulator's sigmoid trials), unless others cancel
///   it: fits with two tracks on one mode and large opposite amplitudes do this.
/// Uses the window transforms gauss_newton left in the fit (its final lambdas).
bool degenerate_fit(const FrameContext& ctx, int m, const FrameFit& fit) {
  const int n = ctx.n, images = ctx.real_signal ? 2 : 1;
  for (int j = 0; j + 1 < n; ++j) {
    if (!(fit.lambda[j].imag() < fit.lambda[j + 1].imag())) return true;
  }
  const auto nb = static_cast<int>(fit.transforms_bins.size());
  if (static_cast<int>(fit.transforms.size()) != nb * n * images) return false;
  double data = 0.0;
  std::vector<double> own(n, 0.0);
  for (int i = 0; i < nb; ++i) {
    const SampledWindow::Transform* t = &fit.transforms[i * n * images];
    for (int c = 0; c < ctx.channels; ++c) {
      data += std::norm(ctx.sg.stft[c](fit.transforms_bins[i], m));
      for (int j = 0; j < n; ++j) {
        cd part = fit.coef(j, c) * t[j * images].w;
        if (images == 2) part += std::conj(fit.coef(j, c)) * t[j * images + 1].w;
        own[j] += std::norm(part);
      }
    }
  }
  const double ratio = std::pow(10.0, ctx.options.max_mode_to_data_db / 10.0);
  return std::any_of(own.begin(), own.end(), [&](double e) { return e > ratio * data; });
}

/// Pass 2 of the chirped frame fits. Pass 1 fitted the frames of `grid` (every stride-th frame),
/// each with chirp rates or without (take_chirped in track_ridges). Here each mode's chirp rate is
/// held at the slope of its pass-1 lambda track over the full-window fits (Savitzky-Golay, order
/// 2, over chirp_slope_window_s; failed or degenerate fits interpolated linearly between their
/// neighbours; beyond the first and last full-window fit, the slope there), and every grid frame's
/// lambdas and amplitudes are refitted from the nearest good full-window pass-1 fit moved along
/// its lambdas and the held rates; then flagged (degenerate_fit, and `misfit`: the model misses
/// the data). The per-frame chirp rates of pass 1 follow the noise where the data barely ask for
/// them; their smoothed track does not, and it reaches the frames of cut windows, where pass 1
/// fits none. The grid frames are independent here: run in parallel, each into its own slot. Every
/// other frame then carries the nearest grid frame's fit moved to its centre.
void hold_chirp_rates(const FrameContext& ctx, std::vector<FrameFit>& fits,
                      const std::vector<int>& grid, int stride) {
  const ReassignedSpectrogram& sg = ctx.sg;
  const int frames = static_cast<int>(fits.size()), n = ctx.n;
  const int points = static_cast<int>(grid.size());
  std::vector<int> good;  // indices into grid: fits not failed nor degenerate
  std::vector<int> full;  // those of them with full windows (pass 1 fitted chirp rates there)
  for (int p = 0; p < points; ++p) {
    if (!fits[grid[p]].ok || fits[grid[p]].degenerate) continue;
    good.push_back(p);
    if (chirp_window(sg, ctx.options, grid[p])) full.push_back(p);
  }
  if (good.empty()) return;
  // The slopes of the lambda tracks of the full-window fits between the first and the last of
  // them (the stationary fits of cut windows lag a chirp), bad points interpolated linearly;
  // beyond them, the slope at the nearest end.
  Eigen::MatrixXd slope = Eigen::MatrixXd::Zero(points, 2 * n);  // too few fits: none
  const double rate_hz = 1.0 / (stride * sg.hop_s);
  if (full.size() >= 3) {
    const int first = full.front(), span = full.back() - first + 1;
    Eigen::MatrixXd track(span, 2 * n);  // Re and Im of lambda_j, 1/s and rad/s
    std::size_t next = 0;                // first full point after p
    for (int p = first; p < first + span; ++p) {
      while (next < full.size() && full[next] <= p) ++next;
      const int a = full[next - 1];
      const int b = next == full.size() ? a : full[next];
      const double w = b == a ? 0.0 : static_cast<double>(p - a) / (b - a);
      for (int j = 0; j < n; ++j) {
        const cd lambda =
            fits[grid[a]].lambda[j] + w * (fits[grid[b]].lambda[j] - fits[grid[a]].lambda[j]);
        track(p - first, 2 * j) = lambda.real();
        track(p - first, 2 * j + 1) = lambda.imag();
      }
    }
    int window = savitzky_golay_window_samples(ctx.options.chirp_slope_window_s, rate_hz);
    if (window > span) window = span % 2 == 1 ? span : span - 1;
    if (window >= 3) {
      SavitzkyGolayOptions smoothing;
      smoothing.window_s = (window - 1) / rate_hz;
      smoothing.polynomial_order = 2;
      slope.middleRows(first, span) = savitzky_golay(track, rate_hz, smoothing).first_derivative;
      for (int p = 0; p < first; ++p) slope.row(p) = slope.row(first);
      for (int p = first + span; p < points; ++p) slope.row(p) = slope.row(first + span - 1);
    }
  }
  // Pass 2 on the grid, each frame from the nearest good full-window pass-1 fit (its own when it
  // is one; the stationary fits of cut windows lag a chirp), or the nearest good fit when there is
  // no full-window one, moved along its lambdas and the held rates; into a copy: the pass-1 fits
  // are read by other points.
  const std::vector<int>& starts = full.empty() ? good : full;
  std::vector<FrameFit> refit(points);
  data::parallel_for_index(static_cast<std::size_t>(points), [&](std::size_t index) {
    const int p = static_cast<int>(index);
    const auto after = std::lower_bound(starts.begin(), starts.end(), p);
    int nearest = after == starts.end() ? starts.back() : *after;
    if (after != starts.begin() && p - *(after - 1) <= nearest - p) nearest = *(after - 1);
    FrameFit fit = fits[grid[nearest]];
    for (int j = 0; j < n; ++j) fit.chirp[j] = cd(slope(p, 2 * j), slope(p, 2 * j + 1));
    move_fit(fit, (grid[p] - grid[nearest]) * sg.hop_s);
    std::vector<int> centres(n);
    for (int j = 0; j < n; ++j) centres[j] = nearest_bin(sg, fit.lambda[j].imag() / (2.0 * M_PI));
    fit.transforms.clear();
    fit.ok = gauss_newton(ctx, grid[p], centres, fit, Chirp::held);
    fit.degenerate = fit.ok && degenerate_fit(ctx, grid[p], fit);
    // A linear chirp over the window cannot follow a stiffness that jumps within it: such fits
    // miss a part of the data far above the noise.
    const double rows = 4.0 * static_cast<double>(fit.transforms_bins.size()) * ctx.channels;
    fit.misfit = fit.ok && fit.relative_cost > ctx.options.max_misfit_fraction &&
                 fit.cost > ctx.options.max_misfit_noise * rows * fit.noise_per_row;
    refit[p] = std::move(fit);
  });
  for (int p = 0; p < points; ++p) fits[grid[p]] = std::move(refit[p]);
  // Every other frame: the nearest grid frame's fit, its model exp(lambda u + g u^2 / 2) moved
  // to the frame's centre (at most stride / 2 hops; the fit describes the whole window), with its
  // flags.
  for (int m = 0; m < frames; ++m) {
    const int p =
        std::clamp(static_cast<int>(std::lround(static_cast<double>(m - grid.front()) / stride)), 0,
                   points - 1);
    if (grid[p] == m) continue;
    FrameFit fit = fits[grid[p]];
    fit.transforms.clear();
    if (fit.ok) move_fit(fit, (m - grid[p]) * sg.hop_s);
    fits[m] = std::move(fit);
  }
}

/// Frames whose fitted frequency lies more than outlier_hz from the median of the mode's other
/// valid fits within +-half_window frames: invalid (a fit that jumped, e.g. onto the other mode,
/// while its neighbours did not).
void flag_outliers(RidgeResult& r, int half_window, double outlier_hz) {
  const int frames = static_cast<int>(r.frequency_hz.rows());
  const int n = static_cast<int>(r.frequency_hz.cols());
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> outlier =
      Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>::Constant(frames, n, false);
  std::vector<double> near;
  for (int j = 0; j < n; ++j) {
    for (int m = 0; m < frames; ++m) {
      if (!r.valid(m, j)) continue;
      near.clear();
      for (int q = std::max(0, m - half_window); q <= std::min(frames - 1, m + half_window); ++q) {
        if (r.valid(q, j)) near.push_back(r.frequency_hz(q, j));
      }
      auto middle = near.begin() + static_cast<long>(near.size() / 2);
      std::nth_element(near.begin(), middle, near.end());
      outlier(m, j) = std::abs(r.frequency_hz(m, j) - *middle) > outlier_hz;
    }
  }
  r.valid = r.valid && !outlier;
}

}  // namespace

void bridge_invalid_frames(RidgeResult& r) {
  const int frames = static_cast<int>(r.frequency_hz.rows());
  const int n = static_cast<int>(r.frequency_hz.cols());
  for (int j = 0; j < n; ++j) {
    const int channels = static_cast<int>(r.amplitude_c[j].cols());
    std::vector<int> good;
    for (int m = 0; m < frames; ++m) {
      if (r.valid(m, j)) good.push_back(m);
    }
    if (good.empty()) {  // no valid frame: only the unresolved ones, from the resolved ones
      for (int m = 0; m < frames; ++m) {
        if (std::isfinite(r.omega_rad_per_s(m, j)) && std::isfinite(r.decay_rate_per_s(m, j)) &&
            r.amplitude_c[j].row(m).allFinite())
          good.push_back(m);
      }
    }
    if (good.empty() || static_cast<int>(good.size()) == frames) continue;
    auto set = [&](int m, double omega, double alpha, const Eigen::VectorXcd& a) {
      r.omega_rad_per_s(m, j) = omega;
      r.frequency_hz(m, j) = omega / (2.0 * M_PI);
      r.decay_rate_per_s(m, j) = alpha;
      for (int c = 0; c < channels; ++c) {
        r.amplitude_c[j](m, c) = a(c);
        r.amplitude[j](m, c) = std::abs(a(c));
        r.phase_rad[j](m, c) = std::arg(a(c));
      }
    };
    auto continued = [&](int from, int m) {  // mode of frame `from` carried to frame m
      const double dt = r.time_s(m) - r.time_s(from);
      const cd lambda(r.decay_rate_per_s(from, j), r.omega_rad_per_s(from, j));
      const Eigen::VectorXcd a = r.amplitude_c[j].row(from).transpose() * std::exp(lambda * dt);
      set(m, lambda.imag(), lambda.real(), a);
    };
    for (int m = 0; m < good.front(); ++m) continued(good.front(), m);
    for (int m = good.back() + 1; m < frames; ++m) continued(good.back(), m);
    for (size_t g = 0; g + 1 < good.size(); ++g) {
      const int m0 = good[g], m1 = good[g + 1];
      if (m1 == m0 + 1) continue;
      const double t0 = r.time_s(m0), span = r.time_s(m1) - t0;
      const double w0 = r.omega_rad_per_s(m0, j), w1 = r.omega_rad_per_s(m1, j);
      const double a0 = r.decay_rate_per_s(m0, j), a1 = r.decay_rate_per_s(m1, j);
      Eigen::VectorXd mismatch(channels);  // phase at m1 minus the integral of omega, wrapped
      for (int c = 0; c < channels; ++c) {
        const double predicted = r.phase_rad[j](m0, c) + 0.5 * (w0 + w1) * span;
        mismatch(c) = std::remainder(r.phase_rad[j](m1, c) - predicted, 2.0 * M_PI);
      }
      for (int m = m0 + 1; m < m1; ++m) {
        const double u = r.time_s(m) - t0, w = u / span;
        const double omega = (1.0 - w) * w0 + w * w1;
        Eigen::VectorXcd a(channels);
        for (int c = 0; c < channels; ++c) {
          const double log_a =
              (1.0 - w) * std::log(r.amplitude[j](m0, c)) + w * std::log(r.amplitude[j](m1, c));
          const double phase =
              r.phase_rad[j](m0, c) + u * (w0 + 0.5 * (omega - w0)) + w * mismatch(c);
          a(c) = std::polar(std::exp(log_a), phase);
        }
        set(m, omega, (1.0 - w) * a0 + w * a1, a);
      }
    }
  }
}

RidgeResult track_ridges(const ReassignedSpectrogram& sg, const RidgeOptions& options) {
  const int n = options.modes;
  const int frames = sg.frames();
  const int channels = sg.channels();
  if (n < 1) throw InputError("ridge tracking: the number of modes must be >= 1");
  if (!(options.max_jump_hz > 0.0) || !(options.jump_penalty_per_hz >= 0.0)) {
    throw InputError("ridge tracking: max jump must be positive and the penalty >= 0");
  }
  if (std::isnan(options.anr_floor_db)) {
    throw InputError(
        "ridge tracking: the amplitude-to-noise floor must be a number of dB (inf: "
        "no floor)");
  }
  const double df = sg.sample_rate_hz / sg.fft_size;
  int band_lo = 0;
  while (band_lo < sg.bins() && sg.frequency_hz(band_lo) < options.min_frequency_hz - 1e-9) {
    ++band_lo;
  }
  int band_hi = sg.bins() - 1;
  while (band_hi >= 0 && sg.frequency_hz(band_hi) > options.max_frequency_hz + 1e-9) --band_hi;
  if (band_hi - band_lo + 1 < n) {
    throw InputError("ridge tracking: the band " + number_text(options.min_frequency_hz) + "-" +
                     number_text(options.max_frequency_hz) + " Hz holds " +
                     std::to_string(std::max(0, band_hi - band_lo + 1)) + " bins of " +
                     number_text(df) + " Hz, fewer than the " + std::to_string(n) + " modes");
  }
  const Eigen::MatrixXd& raw = options.use_reassigned_power ? sg.reassigned_power : sg.power;
  const double floor =
      std::max(1e-300, raw.maxCoeff() * std::pow(10.0, options.power_floor_db / 10.0));
  const Eigen::MatrixXd log_map = (raw.array() + floor).log().matrix();
  const int max_jump_bins = std::max(1, static_cast<int>(std::floor(options.max_jump_hz / df)));

  RidgeResult r;
  r.time_s = sg.time_s;
  r.bin = dp_ridges(log_map, band_lo, band_hi, n, options.jump_penalty_per_hz * df, max_jump_bins);
  r.frequency_hz.resize(frames, n);
  r.omega_rad_per_s.resize(frames, n);
  r.decay_rate_per_s.resize(frames, n);
  r.amplitude.assign(n, Eigen::MatrixXd(frames, channels));
  r.phase_rad.assign(n, Eigen::MatrixXd(frames, channels));
  r.amplitude_c.assign(n, Eigen::MatrixXcd(frames, channels));

  FrameContext ctx{sg, options, n, channels, !sg.analytic};
  std::vector<FrameFit> fits(frames);
  // Frame m fitted with chirp rates from `chirped` replaces the stationary `fit` (ok: whether
  // that converged) when it converges and the stationary fit did not, or when it lowers the sum of
  // squares by more than chirp_min_gain expected noise variances per added unknown (2 per mode):
  // a test of whether the frame's data ask for the chirp rates. Without a noise level, whenever
  // it lowers it.
  auto try_chirped = [&](int m, const std::vector<int>& centres, FrameFit chirped, FrameFit& fit,
                         bool& ok) {
    if (!gauss_newton(ctx, m, centres, chirped, Chirp::fitted)) return;
    if (ok &&
        !(fit.cost - chirped.cost > options.chirp_min_gain * 2.0 * n * chirped.noise_per_row)) {
      return;
    }
    fit = std::move(chirped);
    ok = true;
  };
  // Pass 1. A frame starts from its neighbour's solution moved by the hop(s) between them along
  // its lambdas (and chirp rates), or from the ridges' own starting values when there is none or
  // it fails. The fit bins are those around the ridges; with chirps, around the neighbour's
  // frequencies (the ridges' bins then seed only fits without a neighbour). A degenerate fit is
  // kept, and flagged: started afresh from the ridge it lands elsewhere (measured on the
  // simulator's posture trials: it rescued some runs and broke others; docs/tfa.md).
  auto fit_frame = [&](int m, const FrameFit* warm, double shift_s) {
    std::vector<int> centres(n);
    FrameFit fit;
    bool ok = false;
    const bool chirp = options.fit_chirp && chirp_window(sg, options, m);
    if (warm != nullptr && warm->ok) {
      FrameFit moved = *warm;
      move_fit(moved, shift_s);
      for (int j = 0; j < n; ++j) {
        centres[j] = options.fit_chirp ? nearest_bin(sg, moved.lambda[j].imag() / (2.0 * M_PI))
                                       : r.bin(m, j);
      }
      fit = moved;
      ok = gauss_newton(ctx, m, centres, fit, Chirp::none);
      if (chirp) try_chirped(m, centres, std::move(moved), fit, ok);
    }
    if (!ok) {
      for (int j = 0; j < n; ++j) centres[j] = r.bin(m, j);
      fit = initial_fit(ctx, m, centres);
      ok = fit.ok && gauss_newton(ctx, m, centres, fit, Chirp::none);
      if (ok && chirp) try_chirped(m, centres, fit, fit, ok);
    }
    fit.ok = ok;
    fit.degenerate = ok && degenerate_fit(ctx, m, fit);
    return fit;
  };
  // The start: the middle frame (full windows, best conditioned) or, with chirps, of the first
  // frame with a full window (the modes are strongest just after the pulse), the middle frame and
  // the frame halfway between, the one whose fit is not degenerate and misses the smallest part of
  // its data (relative_cost); if that is degenerate, the frame nearest the middle (later first)
  // whose fit is not. The chains then follow the modes both ways, each frame starting from its
  // neighbour (with chirps: the last frame of its chain whose fit is not degenerate): two
  // independent chains, run in parallel. A chain started from a degenerate fit would carry it
  // along (the constant-K trial at 45 degrees, 20 dB, seed 6: two tracks on the slow mode from
  // the middle frame on, k11 off by 122 %); one started in the middle of a fast stiffening lost
  // the weak mode at 45 degrees (sigmoid K), where the first full frame keeps it.
  int mid = frames / 2;
  FrameFit start = fit_frame(mid, nullptr, 0.0);
  if (options.fit_chirp) {
    int first_full = mid;
    for (int m = 0; m < frames; ++m) {
      if (sg.offset_lo(m) == -sg.half_length && sg.offset_hi(m) == sg.half_length) {
        first_full = m;
        break;
      }
    }
    for (int m : {first_full, (first_full + frames / 2) / 2}) {
      if (m == mid || m >= frames / 2) continue;
      FrameFit fit = fit_frame(m, nullptr, 0.0);
      if (fit.ok && !fit.degenerate &&
          (!start.ok || start.degenerate || fit.relative_cost < start.relative_cost)) {
        start = std::move(fit);
        mid = m;
      }
    }
  }
  for (int d = 1; !(start.ok && !start.degenerate) && d < frames; ++d) {
    for (int m : {frames / 2 + d, frames / 2 - d}) {
      if (m < 0 || m >= frames) continue;
      FrameFit fit = fit_frame(m, nullptr, 0.0);
      if (fit.ok && !fit.degenerate) {
        start = std::move(fit);
        mid = m;
        break;
      }
    }
  }
  fits[mid] = std::move(start);
  // With chirps, pass 1 fits every stride-th frame (about chirp_track_step_s apart: the grid
  // through the start), and so does pass 2.
  const int stride =
      options.fit_chirp
          ? std::max(1, static_cast<int>(std::lround(options.chirp_track_step_s / sg.hop_s)))
          : 1;
  data::parallel_for_index(2, [&](std::size_t chain) {
    const int step = chain == 0 ? stride : -stride;
    int from = mid;
    for (int m = mid + step; m >= 0 && m < frames; m += step) {
      fits[m] = fit_frame(m, &fits[from], (m - from) * sg.hop_s);
      if (!options.fit_chirp || (fits[m].ok && !fits[m].degenerate)) from = m;
    }
  });
  if (options.fit_chirp) {
    std::vector<int> grid;
    for (int m = mid % stride; m < frames; m += stride) grid.push_back(m);
    hold_chirp_rates(ctx, fits, grid, stride);
  }

  int failed_frames = 0;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r.valid.resize(frames, n);
  for (int m = 0; m < frames; ++m) {
    const FrameFit& fit = fits[m];
    if (!fit.ok) ++failed_frames;
    for (int j = 0; j < n; ++j) {
      r.omega_rad_per_s(m, j) = fit.ok ? fit.lambda[j].imag() : nan;
      r.frequency_hz(m, j) = r.omega_rad_per_s(m, j) / (2.0 * M_PI);
      const double f = r.frequency_hz(m, j);
      r.valid(m, j) = fit.ok && !fit.degenerate && !fit.misfit &&
                      std::isfinite(fit.lambda[j].real()) && f >= options.min_frequency_hz &&
                      f <= options.max_frequency_hz;
      r.decay_rate_per_s(m, j) = fit.ok ? fit.lambda[j].real() : nan;
      for (int c = 0; c < channels; ++c) {
        const cd a = !fit.ok           ? cd(nan, nan)
                     : ctx.real_signal ? 2.0 * fit.coef(j, c)
                                       : fit.coef(j, c);
        r.amplitude_c[j](m, c) = a;
        r.amplitude[j](m, c) = std::abs(a);
        r.phase_rad[j](m, c) = std::arg(a);
      }
    }
  }
  for (int m = 0; m < frames; ++m) {  // two fits on one mode: neither is a mode of its own
    for (int j = 0; j + 1 < n; ++j) {
      for (int i = j + 1; i < n; ++i) {
        const double fj = r.frequency_hz(m, j), fi = r.frequency_hz(m, i);
        if (std::abs(fi - fj) < options.min_mode_separation * 0.5 * std::abs(fi + fj)) {
          r.valid(m, j) = false;
          r.valid(m, i) = false;
        }
      }
    }
  }
  if (options.noise_covariance.size() > 0) {  // a mode decayed into the noise is no estimate
    if (options.noise_covariance.rows() != channels || options.noise_covariance.cols() != channels)
      throw InputError("ridge tracking: the noise covariance must be " + std::to_string(channels) +
                       " x " + std::to_string(channels));
    // The noise per channel is at least anr_floor_db below the strongest mode's peak power per
    // channel over the frames valid so far (not the degenerate fits, whose cancelling amplitudes
    // can be huge): noise-free data (a constant pre-onset record) would otherwise give every
    // fitted mode, however small, a ratio of thousands of dB, and no frame would ever be below
    // the threshold.
    double peak_power = 0.0;
    for (int j = 0; j < n; ++j)
      for (int m = 0; m < frames; ++m) {
        if (!r.valid(m, j)) continue;
        const double p = 0.5 * r.amplitude_c[j].row(m).squaredNorm() / channels;
        if (std::isfinite(p)) peak_power = std::max(peak_power, p);
      }
    const double floor = std::pow(10.0, -0.1 * options.anr_floor_db) * peak_power + 1e-300;
    const Eigen::LLT<Eigen::MatrixXcd> llt(options.noise_covariance.cast<cd>() +
                                           floor * Eigen::MatrixXcd::Identity(channels, channels));
    r.anr_db.resize(frames, n);
    for (int j = 0; j < n; ++j)
      for (int m = 0; m < frames; ++m) {
        const Eigen::VectorXcd a = r.amplitude_c[j].row(m).transpose();
        const double power = 0.5 * a.dot(llt.solve(a)).real();
        r.anr_db(m, j) = 10.0 * std::log10(power);
        if (!(r.anr_db(m, j) >= options.anr_threshold_db)) r.valid(m, j) = false;
      }
  }
  if (options.fit_chirp && r.anr_db.rows() == frames) {
    // A free response's modes decay: once a mode's amplitude-to-noise ratio has fallen below the
    // threshold after its peak, its later frames are noise, whatever their own ratio (with chirps
    // only, so that the stationary fits' output is unchanged; the chirped chains otherwise
    // left a few frames of a mode sunk in the noise valid, and the bridge between them sent the
    // mode anywhere: docs/tfa.md).
    for (int j = 0; j < n; ++j) {
      int peak = -1;
      for (int m = 0; m < frames; ++m) {
        if (std::isfinite(r.anr_db(m, j)) && (peak < 0 || r.anr_db(m, j) > r.anr_db(peak, j))) {
          peak = m;
        }
      }
      if (peak < 0) continue;
      int end = frames;
      for (int m = peak; m < frames; ++m) {
        if (std::isfinite(r.anr_db(m, j)) && r.anr_db(m, j) < options.anr_threshold_db) {
          end = m;
          break;
        }
      }
      for (int m = end; m < frames; ++m) r.valid(m, j) = false;
    }
  }
  const int outlier_half_window =
      std::max(1, static_cast<int>(std::lround(0.5 * options.outlier_window_s / sg.hop_s)));
  flag_outliers(r, outlier_half_window, options.outlier_hz);
  // A frame whose fit failed is invalid like any other and bridged; the record fails only when
  // a mode has no valid frame to bridge from while some frame has no values.
  bridge_invalid_frames(r);
  const bool unresolved = !r.omega_rad_per_s.allFinite() || !r.decay_rate_per_s.allFinite();
  if (unresolved) {
    r.status = Status::failure("ridge tracking: " + std::to_string(failed_frames) + " of " +
                               std::to_string(frames) +
                               " frames could not be resolved (no energy at a ridge or a singular "
                               "amplitude fit) and a mode has no valid frame to bridge them from");
  }
  return r;
}

}  // namespace stiffid::estimators
