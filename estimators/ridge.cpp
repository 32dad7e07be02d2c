#include "estimators/ridge.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "data/error.hpp"
#include "data/parallel.hpp"

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
  Eigen::MatrixXcd coef;
  bool ok = false;
  /// Window transforms of the last evaluation (gauss_newton) at these lambdas, window cut and
  /// bins, [bin][mode][image]: a neighbouring frame started from this fit has the same lambdas,
  /// and for interior frames the same cut and usually the same bins, so it reuses them.
  std::vector<SampledWindow::Transform> transforms;
  int transforms_lo = 0, transforms_hi = -1;
  std::vector<int> transforms_bins;
  bool degenerate = false;  ///< not n distinct modes (degenerate_fit)
};

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

/// Gauss-Newton on the frame's exact model of X_h and X_dh at the fit bins (ridge bins +- q) in
/// all channels: unknowns Re/Im lambda_j and Re/Im c_jk, derivatives from the window transforms
/// (dW/ds = Wt, dWd/ds = Wdt). X_dh is weighted by T / (2 pi) to match the scale of X_h.
bool gauss_newton(const FrameContext& ctx, int m, const std::vector<int>& ridge, FrameFit& fit) {
  const ReassignedSpectrogram& sg = ctx.sg;
  const double dt = 1.0 / sg.sample_rate_hz;
  const SampledWindow::Cut cut = sg.frame_window(m);
  const int n = ctx.n, channels = ctx.channels;
  std::vector<int> bins;
  for (int j = 0; j < n; ++j) {
    for (int d = -ctx.options.fit_half_width_bins; d <= ctx.options.fit_half_width_bins; ++d) {
      const int k = ridge[j] + d;
      if (k >= 0 && k < sg.bins()) bins.push_back(k);
    }
  }
  std::sort(bins.begin(), bins.end());
  bins.erase(std::unique(bins.begin(), bins.end()), bins.end());
  const int nb = static_cast<int>(bins.size());
  const double wd_weight = (cut.hi - cut.lo) * dt / (2.0 * M_PI);
  const int unknowns = 2 * n + 2 * n * channels;
  const int rows = 2 * 2 * nb * channels;  // (h, dh) x bins x channels, real and imaginary
  const int images = ctx.real_signal ? 2 : 1;

  // Fills f.transforms for f.lambda (unless they are already those of this cut and these bins),
  // then the residual and the Jacobian.
  auto evaluate = [&](FrameFit& f, Eigen::VectorXd& residual, Eigen::MatrixXd* jac,
                      bool transforms_current) {
    if (!transforms_current || f.transforms_lo != cut.lo || f.transforms_hi != cut.hi ||
        f.transforms_bins != bins) {
      f.transforms.resize(nb * n * images);
      for (int i = 0; i < nb; ++i) {
        const double nu = 2.0 * M_PI * sg.frequency_hz(bins[i]);
        for (int j = 0; j < n; ++j) {
          auto* t = &f.transforms[(i * n + j) * images];
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
          }
          if (jac) {
            const int cols[4] = {2 * j, 2 * j + 1, 2 * n + 2 * (j * channels + c),
                                 2 * n + 2 * (j * channels + c) + 1};
            const cd dh[4] = {dh_dp, dh_dq, dh_dre, dh_dim};
            const cd dd[4] = {dd_dp, dd_dq, dd_dre, dd_dim};
            for (int q = 0; q < 4; ++q) {
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
        trial.lambda[j] = fit.lambda[j] + scale * cd(step(2 * j), step(2 * j + 1));
        for (int c = 0; c < channels; ++c) {
          const int col = 2 * n + 2 * (j * channels + c);
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
      const double lambda_step =
          std::abs(trial.lambda[j] - fit.lambda[j]) / std::abs(fit.lambda[j]);
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
          const double log_a = (1.0 - w) * std::log(r.amplitude[j](m0, c)) +
                               w * std::log(r.amplitude[j](m1, c));
          const double phase = r.phase_rad[j](m0, c) + u * (w0 + 0.5 * (omega - w0)) +
                               w * mismatch(c);
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
  const double df = sg.sample_rate_hz / sg.fft_size;
  int band_lo = 0;
  while (band_lo < sg.bins() && sg.frequency_hz(band_lo) < options.min_frequency_hz - 1e-9) {
    ++band_lo;
  }
  int band_hi = sg.bins() - 1;
  while (band_hi >= 0 && sg.frequency_hz(band_hi) > options.max_frequency_hz + 1e-9) --band_hi;
  if (band_hi - band_lo + 1 < n) {
    throw InputError("ridge tracking: the band " + number_text(options.min_frequency_hz) +
                     "-" + number_text(options.max_frequency_hz) + " Hz holds " +
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
  // A frame starts from its neighbour's solution moved by one hop, or from the ridge's own
  // starting values when there is none or it fails. A degenerate fit is kept, and flagged: started
  // afresh from the ridge it lands elsewhere, and the chain that follows it does too (measured on
  // the simulator's posture trials: it rescued some runs and broke others; docs/tfa.md).
  auto fit_frame = [&](int m, const FrameFit* warm, double shift_s) {
    std::vector<int> ridge(n);
    for (int j = 0; j < n; ++j) ridge[j] = r.bin(m, j);
    FrameFit fit;
    bool ok = false;
    if (warm != nullptr && warm->ok) {
      fit = *warm;
      for (int j = 0; j < n; ++j) fit.coef.row(j) *= std::exp(fit.lambda[j] * shift_s);
      ok = gauss_newton(ctx, m, ridge, fit);
    }
    if (!ok) {
      fit = initial_fit(ctx, m, ridge);
      ok = fit.ok && gauss_newton(ctx, m, ridge, fit);
    }
    fit.ok = ok;
    fit.degenerate = ok && degenerate_fit(ctx, m, fit);
    return fit;
  };
  // Start mid-record (full windows, best conditioned) at the frame nearest the middle (later
  // first) whose fit is not degenerate, then follow the modes both ways, each frame starting from
  // its neighbour's solution: two independent chains, run in parallel. A chain started from a
  // degenerate fit would carry it along (the constant-K trial at 45 degrees, 20 dB, seed 6: two
  // tracks on the slow mode from the middle frame on, k11 off by 122 %).
  int mid = frames / 2;
  FrameFit start = fit_frame(mid, nullptr, 0.0);
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
  data::parallel_for_index(2, [&](std::size_t chain) {
    if (chain == 0) {
      for (int m = mid + 1; m < frames; ++m) fits[m] = fit_frame(m, &fits[m - 1], sg.hop_s);
    } else {
      for (int m = mid - 1; m >= 0; --m) fits[m] = fit_frame(m, &fits[m + 1], -sg.hop_s);
    }
  });

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
      r.valid(m, j) = fit.ok && !fit.degenerate && std::isfinite(fit.lambda[j].real()) &&
                      f >= options.min_frequency_hz && f <= options.max_frequency_hz;
      r.decay_rate_per_s(m, j) = fit.ok ? fit.lambda[j].real() : nan;
      for (int c = 0; c < channels; ++c) {
        const cd a = !fit.ok ? cd(nan, nan) : ctx.real_signal ? 2.0 * fit.coef(j, c) : fit.coef(j, c);
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
    const Eigen::LLT<Eigen::MatrixXcd> llt(options.noise_covariance.cast<cd>() +
                                           1e-300 * Eigen::MatrixXcd::Identity(channels, channels));
    r.anr_db.resize(frames, n);
    for (int j = 0; j < n; ++j)
      for (int m = 0; m < frames; ++m) {
        const Eigen::VectorXcd a = r.amplitude_c[j].row(m).transpose();
        const double power = 0.5 * a.dot(llt.solve(a)).real();
        r.anr_db(m, j) = 10.0 * std::log10(power);
        if (!(r.anr_db(m, j) >= options.anr_threshold_db)) r.valid(m, j) = false;
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
