#include "estimators/damped_modes.hpp"

#include <ceres/ceres.h>

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "data/parallel.hpp"
#include "estimators/cubic_bspline.hpp"
#include "estimators/decimate.hpp"
#include "estimators/differences.hpp"
#include "estimators/effective_parameters.hpp"
#include "estimators/normal_equations.hpp"

namespace stiffid::estimators {
namespace {

using Complex = std::complex<double>;
using RowMajor = RowMajorMatrix;  // normal_equations.hpp

// The most by which the whitened energies of the modes' parts of a fit may add up to more than
// the energy of their sum before the modes count as cancelling (one mode explained by two
// opposed oscillations; fit_damped_modes, `spurious`). Modes at distinct frequencies dephase
// within the record and their energies add: 0.8-1.6 in the candidates of the posture trials
// inspected, 2.1-2.5 where a mode's amplitude jumps (a sharp stiffness change, x5 in 0.15 s, at
// 0 degrees; the smoothest fit of sigmoid K at 0 degrees), 6.0-17.8 in the cancelling fits that
// lost trials (docs/tfa_modal.md, "Cancelling modes").
constexpr double kMaxCancellation = 4.0;

// Filtered, decimated free response and the whitening that makes its noise white with unit
// variance in every channel.
struct Prepared {
  Eigen::VectorXd t_s;        // [N] absolute times, s
  Eigen::VectorXd tau_s;      // [N] from the first fitted sample, s
  Eigen::MatrixXd y;          // (N x C) data, channel units
  Eigen::VectorXd yw;         // [N C] whitened data, row i * C + k
  Eigen::MatrixXd cholesky;   // (C x C) L with noise covariance = L L^T
  Eigen::MatrixXd whiten;     // (C x C) W = L^-1
  Eigen::MatrixXd noise_cov;  // (C x C)
  double rate_hz = 0.0;
};

void check_options(const DampedModesOptions& o) {
  auto fail = [](const std::string& key, const std::string& what) {
    throw InputError("modal fit: option " + key + " " + what);
  };
  if (o.modes < 1) fail("modes", "must be at least 1");
  if (!(o.knot_spacing_s > 0.0)) fail("knot_spacing_s", "must be positive (s)");
  if (!(o.noise_window_s > 0.0)) fail("noise_window_s", "must be positive (s)");
  if (!(o.skip_s >= 0.0)) fail("skip_s", "must be non-negative (s)");
  if (o.track_roughness == 0.0 || !std::isfinite(o.track_roughness))
    fail("track_roughness", "must be positive (rad/s), or negative for the choice from the data");
  if (!(o.init_window_s > 0.0)) fail("init_window_s", "must be positive (s)");
  if (!(o.init_max_rate_hz >= 0.0)) fail("init_max_rate_hz", "must be >= 0 (Hz; 0: no limit)");
  if (!(o.sliding_window_s > 0.0)) fail("sliding_window_s", "must be positive (s)");
  if (!(o.max_frequency_sd_hz > 0.0)) fail("max_frequency_sd_hz", "must be positive (Hz)");
  if (!std::isfinite(o.max_mode_to_data_db)) fail("max_mode_to_data_db", "must be finite (dB)");
  if (!(o.min_mode_separation >= 0.0 && o.min_mode_separation < 1.0))
    fail("min_mode_separation", "must be in [0, 1)");
  if (o.max_iterations < 1) fail("max_iterations", "must be at least 1");
  if (!(o.shape_phase_factor > 0.0 && std::isfinite(o.shape_phase_factor)))
    fail("shape_phase_factor (--shape-phase-factor)", "must be positive and finite");
  if (!(o.local_roughness_dof >= 0.0 && std::isfinite(o.local_roughness_dof)))
    fail("local_roughness_dof (--local-roughness-dof)",
         "must be non-negative and finite (0: one roughness for the whole record)");
  if (!std::isfinite(o.lost_track_time_s))
    fail("lost_track_time_s (--lost-track-time-s)",
         "must be finite (s; 0: held; negative: the splines' straight line)");
  if (!std::isfinite(o.decay_tie))
    fail("decay_tie (--decay-tie)", "must be finite (relative SD; 0: no tie)");
  if (!std::isfinite(o.frequency_tie))
    fail("frequency_tie (--frequency-tie)", "must be finite (relative SD; 0: no tie)");
}

Prepared prepare(const Eigen::Ref<const Eigen::MatrixXd>& x, double rate_hz, double start_s,
                 double onset_s, const DampedModesOptions& o) {
  const int s = static_cast<int>(x.rows());
  const int c = static_cast<int>(x.cols());
  if (!(rate_hz > 0.0)) throw InputError("modal fit: sample rate must be positive");
  if (c < 1) throw InputError("modal fit: no channels");
  if (!x.allFinite()) throw InputError("modal fit: deviations contain NaN or infinity");
  // Zero-phase Kaiser FIR with the short filter of decimate.hpp (25 ms at 4 kHz -> 200 Hz): the
  // first 25 ms after skip_s are the only samples whose filter reaches the pulse.
  const DecimationOptions decimation = short_filter_decimation(
      o.decimate_hz > 0.0 ? std::max(1, static_cast<int>(std::lround(rate_hz / o.decimate_hz)))
                          : 1);
  const int d = decimation.factor;
  const int h = filter_reach_samples(decimation);
  const int onset = static_cast<int>(std::ceil((onset_s - start_s) * rate_hz - 1e-9));
  if (onset < 0 || onset >= s)
    throw InputError("modal fit: onset " + number_text(onset_s) + " s is outside the record [" +
                     number_text(start_s) + ", " + number_text(start_s + s / rate_hz) + ") s");
  auto up = [d](int i) { return i >= 0 ? (i + d - 1) / d : -((-i) / d); };  // ceil(i / d)
  const int noise_first =
      up(std::max(h, onset - static_cast<int>(std::lround(o.noise_window_s * rate_hz)) + h));
  const int noise_last = (onset - 1 - h) >= 0 ? (onset - 1 - h) / d : -1;
  if (noise_last - noise_first + 1 < 8 * c || onset < std::lround(o.noise_window_s * rate_hz))
    throw InputError("modal fit: the record needs noise_window_s = " +
                     number_text(o.noise_window_s) + " s of samples before the onset (plus " +
                     number_text(h / rate_hz) + " s for the decimation filter)");
  const int first = up(onset + static_cast<int>(std::ceil(o.skip_s * rate_hz)) + h);
  const int last = (s - 1 - h) / d;
  const int n = std::max(0, last - first + 1);
  Prepared p;
  p.rate_hz = rate_hz / d;
  if (n < 2 || (n - 1) / p.rate_hz < 0.5)
    throw InputError("modal fit: less than 0.5 s of free response after onset + skip_s (" +
                     number_text(n / p.rate_hz) + " s)");
  const DecimationResult decimated = decimate(x, rate_hz, decimation);
  p.y = decimated.samples.middleRows(first, n);
  p.t_s = start_s + Eigen::VectorXd::LinSpaced(n, first, last).array() * (d / rate_hz);
  p.tau_s = p.t_s.array() - p.t_s(0);

  Eigen::MatrixXd noise = decimated.samples.middleRows(noise_first, noise_last - noise_first + 1);
  noise.rowwise() -= noise.colwise().mean();
  p.noise_cov = noise.transpose() * noise / double(noise.rows() - 1);
  // Floor for (nearly) noise-free data: the noise per channel is topped up to 1e-4 of the signal
  // power (40 dB SNR), and never less than 1e-6 of it is added. The nonlinear arm's model error
  // (Coriolis terms, the joint-to-hand geometry) is about -40 dB of its linear two-mode response:
  // with a lower floor the whitened residual is that model error, the tracks chase it and a
  // barely excited mode fits it (60 dB floor, noise-free posture trials: k11 off by 39 % at 0
  // degrees, 2-5 % at 90/135; 40 dB: 0.1-0.5 %; scipy posture fixtures: sigmoid K lost at a
  // 1e-12 floor). Data whose (filtered) noise is below 1e-4 of the response power are fitted as
  // such; noisier data as before (the 1e-6 term only).
  const double power = p.y.squaredNorm() / double(p.y.size());
  const double floor =
      std::max(1e-6 * power, 1e-4 * power - p.noise_cov.trace() / double(c)) + 1e-300;
  const Eigen::MatrixXd cov = p.noise_cov + floor * Eigen::MatrixXd::Identity(c, c);
  const Eigen::LLT<Eigen::MatrixXd> llt(cov);
  p.cholesky = llt.matrixL();
  p.whiten = p.cholesky.triangularView<Eigen::Lower>().solve(Eigen::MatrixXd::Identity(c, c));
  const Eigen::MatrixXd yw = p.y * p.whiten.transpose();  // (N x C)
  p.yw = Eigen::Map<const Eigen::VectorXd>(Eigen::MatrixXd(yw.transpose()).data(), n * c);
  return p;
}

// One real linear parameter pair (Re, Im of a complex coefficient) of the variable projection:
// whitened contribution Re(coef * direction_k * F(t, function) * exp(Phi_j(t))) in channel k.
struct LinearTerm {
  int mode;
  Eigen::VectorXcd direction;  // [C] in whitened channel space
  int function;                // column of the time-function matrix
};

// Soft tie of one kind of track (part 0: the decays alpha_j, part 1: the frequencies omega_j):
// the spline coefficients of mode j > 0 follow rho_j times those of mode 0 (so alpha_j(t) =
// rho_j alpha_0(t), or omega_j(t) = rho_j omega_0(t), when the tie holds exactly), with prior SD
// sd * scale(j) per coefficient; the ratios rho_j are extra parameters after the tracks' (flat
// prior). The decay tie holds when stiffness and damping change by a common factor, the
// frequency tie when the stiffness does, whatever the damping (docs/tfa_modal.md).
struct TrackTie {
  double sd = 0.0;        // relative prior SD; 0: no tie
  Eigen::VectorXd scale;  // [n] 1/s or rad/s, mode j's mean |coefficient| when the search began
};
using TrackTies = std::array<TrackTie, 2>;  // the decay tie, the frequency tie

// Variable-projection problem for fixed linear terms and shape penalty. Parameters: the track
// coefficients (2 n M), the decay tie's ratios (n - 1 with that tie), the frequency tie's (n - 1
// with that tie), the real terms' rates (R, 1/s).
// Linear parameters: Re, Im of each LinearTerm, then the real terms' whitened amplitudes (R C),
// then, with offsets, a constant whitened offset per channel (C), then, with a second-order mode
// j, per whitened channel the amplitude of exp(2 Re Phi_j) and Re, Im of that of exp(2 Phi_j)
// (3 C).
class VpProblem {
 public:
  // `track_values` (N x M), the track basis at the samples: given, the decay coefficients are
  // the modal damping -Gamma_j and Re Phi_j = int(-Gamma_j) - ln(omega_j) / 2
  // (DecayTracks::gamma); empty, they are alpha_j and Re Phi_j = int alpha_j.
  VpProblem(const Prepared& p, int modes, const Eigen::MatrixXd& phase_integrals,
            const Eigen::MatrixXd& track_values, const Eigen::MatrixXd& functions,
            std::vector<LinearTerm> terms, std::vector<std::pair<int, int>> penalized_pairs,
            double shape_weight, const Eigen::MatrixXd& prior_rows, TrackTies ties, int real_terms,
            bool offsets, int second_order_mode = -1, double phase_factor = 1.0)
      : p_(p),
        modes_(modes),
        ig_(phase_integrals),
        wv_(track_values),
        f_(functions),
        terms_(std::move(terms)),
        pairs_(std::move(penalized_pairs)),
        sqrt_weight_(std::sqrt(shape_weight)),
        sqrt_phase_(std::sqrt(phase_factor)),
        prior_(prior_rows),
        ties_(std::move(ties)),
        real_(real_terms),
        offsets_(offsets ? static_cast<int>(p.whiten.rows()) : 0),
        so_mode_(second_order_mode) {}

  int basis() const { return static_cast<int>(ig_.cols()); }
  int track_parameters() const { return 2 * modes_ * basis(); }
  // Modes tied by the tie of part 0 (decays) or 1 (frequencies), and where its ratios are.
  int tied(int part) const { return ties_[part].sd > 0.0 ? modes_ - 1 : 0; }
  int first_ratio(int part) const { return track_parameters() + (part == 1 ? tied(0) : 0); }
  int tied_modes() const { return tied(0) + tied(1); }
  int real_terms() const { return real_; }
  int first_rate() const { return track_parameters() + tied_modes(); }
  int parameters() const { return first_rate() + real_; }
  int complex_linear() const { return 2 * static_cast<int>(terms_.size()); }
  int first_offset() const { return complex_linear() + real_ * static_cast<int>(p_.whiten.rows()); }
  int first_so() const { return first_offset() + offsets_; }
  int so_count() const { return so_mode_ >= 0 ? 3 * static_cast<int>(p_.whiten.rows()) : 0; }
  int second_order_mode() const { return so_mode_; }
  int linear() const { return first_so() + so_count(); }
  int data_rows() const { return static_cast<int>(p_.yw.size()); }
  int penalty_rows() const { return 2 * static_cast<int>(pairs_.size()); }
  int tie_rows() const { return tied_modes() * basis(); }
  int residuals() const {
    return data_rows() + penalty_rows() + static_cast<int>(prior_.rows()) + tie_rows();
  }

  // An evaluation with its Jacobian: the point, the residuals (residuals()), the Jacobian
  // (residuals() x parameters()) and the linear solution (linear()).
  struct Evaluation {
    Eigen::VectorXd theta, residual;
    RowMajor jacobian;
    Eigen::VectorXd beta;
  };
  // Keeps `e`, the last Jacobian a solve evaluated (solve()): where the solve ended, so that
  // what reads the fit there (evaluated(): fit_size, the sliding windows, the final report) need
  // not evaluate again.
  void remember(Evaluation&& e) const { last_ = std::move(e); }
  // The remembered evaluation if it is at exactly `theta` (every bit), else null.
  const Evaluation* evaluation_at(const Eigen::VectorXd& theta) const {
    const bool same = last_.theta.size() == theta.size() && theta.size() > 0 &&
                      std::memcmp(last_.theta.data(), theta.data(),
                                  sizeof(double) * static_cast<std::size_t>(theta.size())) == 0;
    return same ? &last_ : nullptr;
  }

  // exp(beta_r tau_i) for every real term: (N x R); false on overflow.
  bool real_exponentials(const double* theta, Eigen::MatrixXd& er) const {
    er.resize(p_.tau_s.size(), real_);
    for (int r = 0; r < real_; ++r) {
      const double beta = theta[first_rate() + r];
      if (!std::isfinite(beta) || beta * p_.tau_s(p_.tau_s.size() - 1) > 600.0) return false;
      er.col(r) = (beta * p_.tau_s.array()).exp().matrix();
    }
    return true;
  }

  bool damping_tracks() const { return wv_.size() > 0; }
  // exp(Phi_j(tau_i)) for every mode: (N x n); false on overflow or, with damping tracks, a
  // frequency track not positive everywhere. With damping tracks, also -1 / (2 omega_j(tau_i))
  // in half_inverse_omega_ (d Re Phi_j / d omega_j).
  bool oscillations(const double* theta, Eigen::MatrixXcd& e) const {
    const int m = basis();
    e.resize(ig_.rows(), modes_);
    if (damping_tracks()) half_inverse_omega_.resize(ig_.rows(), modes_);
    for (int j = 0; j < modes_; ++j) {
      const Eigen::Map<const Eigen::VectorXd> cw(theta + (2 * j + 1) * m, m);
      Eigen::VectorXd re = ig_ * Eigen::Map<const Eigen::VectorXd>(theta + 2 * j * m, m);
      const Eigen::VectorXd im = ig_ * cw;
      if (damping_tracks()) {
        const Eigen::ArrayXd omega = (wv_ * cw).array();
        if (!(omega > 0.0).all()) return false;
        re.array() -= 0.5 * omega.log();
        half_inverse_omega_.col(j) = -0.5 * omega.inverse();
      }
      if (!re.allFinite() || !im.allFinite() || re.cwiseAbs().maxCoeff() > 600.0) return false;
      for (Eigen::Index i = 0; i < re.size(); ++i) e(i, j) = std::exp(Complex(re(i), im(i)));
    }
    return true;
  }

  // Design matrix of the linear parameters: data rows then shape-penalty rows (without weight).
  void design(const Eigen::MatrixXcd& e, const Eigen::MatrixXd& er, Eigen::MatrixXd& a_data,
              Eigen::MatrixXd& a_penalty) const {
    const int n = static_cast<int>(e.rows());
    const int c = static_cast<int>(p_.whiten.rows());
    a_data.setZero(data_rows(), linear());
    for (size_t t = 0; t < terms_.size(); ++t) {
      const LinearTerm& term = terms_[t];
      for (int i = 0; i < n; ++i) {
        const Complex v = f_(i, term.function) * e(i, term.mode);
        for (int k = 0; k < c; ++k) {
          const Complex w = term.direction(k) * v;
          a_data(i * c + k, 2 * t) = w.real();
          a_data(i * c + k, 2 * t + 1) = -w.imag();
        }
      }
    }
    for (int r = 0; r < real_; ++r)
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < c; ++k) a_data(i * c + k, complex_linear() + r * c + k) = er(i, r);
    for (int k = 0; k < offsets_; ++k)
      for (int i = 0; i < n; ++i) a_data(i * c + k, first_offset() + k) = 1.0;
    if (so_mode_ >= 0)
      for (int i = 0; i < n; ++i) {
        const Complex e2 = e(i, so_mode_) * e(i, so_mode_);  // exp(2 Phi_j)
        const double dc = std::norm(e(i, so_mode_));         // exp(2 Re Phi_j)
        for (int k = 0; k < c; ++k) {
          a_data(i * c + k, first_so() + 3 * k) = dc;
          a_data(i * c + k, first_so() + 3 * k + 1) = e2.real();
          a_data(i * c + k, first_so() + 3 * k + 2) = -e2.imag();
        }
      }
    a_penalty.setZero(penalty_rows(), linear());
    // Re (part 0) and Im (part 1) of the coefficients' first differences; Im weighted by the
    // phase factor (the shape design's directions are turned so that Im is the phase part).
    for (size_t q = 0; q < pairs_.size(); ++q)
      for (int part = 0; part < 2; ++part) {
        const double scale = part == 0 ? 1.0 : sqrt_phase_;
        a_penalty(2 * q + part, 2 * pairs_[q].first + part) = -scale;
        a_penalty(2 * q + part, 2 * pairs_[q].second + part) = scale;
      }
  }

  // Residuals [whitened data; shape penalty; track prior] and, when asked, Kaufman's Jacobian
  // (row-major, residuals x parameters). Returns the linear solution in `linear_out`.
  bool evaluate(const double* theta, double* residuals, double* jacobian,
                Eigen::VectorXd* linear_out) const {
    // Work buffers are members (one solve uses a problem at a time): a fresh ~1 MB Jacobian
    // workspace per evaluation cost more in page faults than the arithmetic.
    Eigen::MatrixXcd& e = e_;
    if (!oscillations(theta, e) || !real_exponentials(theta, er_)) return false;
    design(e, er_, a_data_, a_penalty_);
    const int rd = data_rows(), rp = penalty_rows(), nl = linear(), np = parameters();
    Eigen::MatrixXd& a = a_;
    a.resize(rd + rp, nl);
    a << a_data_, sqrt_weight_ * a_penalty_;
    b_.setZero(rd + rp);
    b_.head(rd) = p_.yw;
    qr_.compute(a);
    const Eigen::VectorXd beta = qr_.solve(b_);
    if (!beta.allFinite()) return false;
    const Eigen::Map<const Eigen::VectorXd> th(theta, np);
    Eigen::Map<Eigen::VectorXd> r(residuals, residuals_count());
    r.head(rd + rp) = b_ - a * beta;
    const int rr = static_cast<int>(prior_.rows()), m = basis(), tp = track_parameters();
    r.segment(rd + rp, rr) = prior_ * th.head(tp);
    for (int part = 0, row = rd + rp + rr; part < 2; ++part)
      for (int j = 1; j <= tied(part); ++j, row += m) {
        const double rho = th(first_ratio(part) + j - 1);
        const double inv = 1.0 / (ties_[part].sd * ties_[part].scale(j));
        r.segment(row, m) =
            inv * (th.segment((2 * j + part) * m, m) - rho * th.segment(part * m, m));
      }
    if (linear_out) *linear_out = beta;
    if (!jacobian) return true;

    // D = d(A beta)/d theta with beta held fixed: the phase coefficients of mode j move the
    // whitened contribution Y_j by (integral of B_m) times Y_j (alpha) or i Y_j (omega); with
    // damping tracks omega also moves it by -B_m / (2 omega_j) times Y_j.
    const int c = static_cast<int>(p_.whiten.rows());
    const int n = static_cast<int>(e.rows());
    const Eigen::MatrixXcd& contribution = mode_contributions(e, beta);
    Eigen::MatrixXd& d = d_;
    d.setZero(rd + rp, np);
    const bool damping = damping_tracks();
    for (int j = 0; j < modes_; ++j)
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < c; ++k) {
          const Complex y = contribution(i * c + k, j);
          const double amplitude_rate = damping ? half_inverse_omega_(i, j) * y.real() : 0.0;
          for (int q = 0; q < m; ++q) {
            const double g = ig_(i, q);
            if (g == 0.0 && (!damping || wv_(i, q) == 0.0)) continue;
            d(i * c + k, 2 * j * m + q) = g * y.real();
            d(i * c + k, (2 * j + 1) * m + q) =
                -g * y.imag() + (damping ? wv_(i, q) * amplitude_rate : 0.0);
          }
        }
    if (so_mode_ >= 0) {
      const int j = so_mode_;
      for (int i = 0; i < n; ++i) {
        const Complex e2 = e(i, j) * e(i, j);
        const double dc = std::norm(e(i, j));
        for (int k = 0; k < c; ++k) {
          const double ydc = 2.0 * dc * beta(first_so() + 3 * k);
          const Complex y2 =
              2.0 * Complex(beta(first_so() + 3 * k + 1), beta(first_so() + 3 * k + 2)) * e2;
          const double amplitude_rate =
              damping ? half_inverse_omega_(i, j) * (ydc + y2.real()) : 0.0;
          for (int q = 0; q < m; ++q) {
            const double g = ig_(i, q);
            if (g == 0.0 && (!damping || wv_(i, q) == 0.0)) continue;
            d(i * c + k, 2 * j * m + q) += g * (ydc + y2.real());
            d(i * c + k, (2 * j + 1) * m + q) +=
                -g * y2.imag() + (damping ? wv_(i, q) * amplitude_rate : 0.0);
          }
        }
      }
    }
    // A real term's rate moves its contribution b_rk exp(beta_r tau) by tau times it.
    for (int r = 0; r < real_; ++r)
      for (int i = 0; i < n; ++i)
        for (int k = 0; k < c; ++k)
          d(i * c + k, first_rate() + r) =
              p_.tau_s(i) * er_(i, r) * beta(complex_linear() + r * c + k);
    // -(I - Q Q^T) D with Q the first `rank` columns of the QR's orthogonal factor (the range
    // of A), formed once: two matrix products, several times faster than applying the
    // reflectors to D column by column.
    const int rank = static_cast<int>(qr_.rank());
    q_.setIdentity(rd + rp, rank);
    q_.applyOnTheLeft(qr_.householderQ().setLength(rank));
    qtd_.noalias() = q_.transpose() * d;
    d.noalias() -= q_ * qtd_;
    Eigen::Map<RowMajor> jac(jacobian, residuals_count(), np);
    jac.topRows(rd + rp) = -d;
    jac.block(rd + rp, 0, rr + tie_rows(), np).setZero();
    jac.block(rd + rp, 0, rr, tp) = prior_;
    for (int part = 0, row = rd + rp + rr; part < 2; ++part)
      for (int j = 1; j <= tied(part); ++j) {
        const int ratio = first_ratio(part) + j - 1;
        const double rho = th(ratio), inv = 1.0 / (ties_[part].sd * ties_[part].scale(j));
        for (int q = 0; q < m; ++q, ++row) {
          jac(row, (2 * j + part) * m + q) = inv;
          jac(row, part * m + q) = -rho * inv;
          jac(row, ratio) = -inv * th(part * m + q);
        }
      }
    return true;
  }

  // Whitened energies at theta, over the record: of each mode's part of the model (`modes`), of
  // their sum (`sum`) and of the second-order terms' part (`distortion`, 0 without them). False
  // when theta does not evaluate.
  struct PartEnergies {
    Eigen::VectorXd modes;
    double sum = 0.0, distortion = 0.0;
  };
  bool part_energies(const double* theta, PartEnergies& out) const {
    std::vector<double> scratch(residuals());
    Eigen::VectorXd beta;
    if (!evaluate(theta, scratch.data(), nullptr, &beta)) return false;
    const Eigen::MatrixXd parts = mode_contributions(e_, beta).real();
    out.modes = parts.colwise().squaredNorm().transpose();
    out.sum = parts.rowwise().sum().squaredNorm();
    out.distortion =
        (a_data_.middleCols(first_so(), so_count()) * beta.segment(first_so(), so_count()))
            .squaredNorm();
    return true;
  }

  int residuals_count() const { return residuals(); }
  const std::vector<LinearTerm>& terms() const { return terms_; }
  double shape_weight() const { return sqrt_weight_ * sqrt_weight_; }

 private:
  // Whitened part of the model of each mode at the linear solution beta ((N C) x modes; the model
  // is its real part), in the work buffer contribution_.
  const Eigen::MatrixXcd& mode_contributions(const Eigen::MatrixXcd& e,
                                             const Eigen::VectorXd& beta) const {
    const int c = static_cast<int>(p_.whiten.rows());
    const int n = static_cast<int>(e.rows());
    contribution_.setZero(n * c, modes_);
    for (size_t t = 0; t < terms_.size(); ++t) {
      const LinearTerm& term = terms_[t];
      const Complex coef(beta(2 * t), beta(2 * t + 1));
      for (int i = 0; i < n; ++i) {
        const Complex v = coef * f_(i, term.function) * e(i, term.mode);
        for (int k = 0; k < c; ++k) contribution_(i * c + k, term.mode) += term.direction(k) * v;
      }
    }
    return contribution_;
  }

  const Prepared& p_;
  int modes_;
  Eigen::MatrixXd ig_;  // (N x M) running integrals of the track basis, s
  Eigen::MatrixXd wv_;  // (N x M) the track basis (damping tracks), or empty
  Eigen::MatrixXd f_;   // (N x F) time functions of the linear terms
  std::vector<LinearTerm> terms_;
  std::vector<std::pair<int, int>> pairs_;  // linear terms whose difference is penalized
  double sqrt_weight_;
  double sqrt_phase_;      // sqrt of the phase factor of the shape penalty (design())
  Eigen::MatrixXd prior_;  // (R x 2 n M) roughness prior rows on the track coefficients
  TrackTies ties_;
  int real_;     // R real terms
  int offsets_;  // C constant offsets (whitened), or 0
  int so_mode_;  // mode j whose second-order terms are fitted (exp(2 Re Phi_j), exp(2 Phi_j)), or
                 // -1
  // Work buffers of evaluate().
  mutable Eigen::MatrixXcd e_, contribution_;
  mutable Eigen::MatrixXd half_inverse_omega_;  // (N x n) -1 / (2 omega_j), damping tracks
  mutable Eigen::MatrixXd er_, a_data_, a_penalty_, a_, d_, q_, qtd_;
  mutable Eigen::VectorXd b_;
  mutable Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr_;
  mutable Evaluation last_;  // remember()
};

// The variable-projection problem as Ceres sees it: compressed to p + 1 residuals
// (compress_least_squares) with the same cost, gradient and Gauss-Newton matrix, so the same
// Levenberg-Marquardt steps (DENSE_NORMAL_CHOLESKY forms J^T J anyway), while Ceres's linear
// algebra, copies and checks run on p + 1 rows instead of the ~1000 of the record
// (docs/tfa_modal.md, "Speed"). Without a Jacobian only the cost is asked for: |r| in one entry.
class VpCost final : public ceres::CostFunction {
 public:
  explicit VpCost(const VpProblem& problem)
      : problem_(problem),
        residual_(problem.residuals()),
        at_jacobian_{Eigen::VectorXd(), Eigen::VectorXd(problem.residuals()),
                     RowMajor(problem.residuals(), problem.parameters()), Eigen::VectorXd()} {
    set_num_residuals(problem.parameters() + 1);
    mutable_parameter_block_sizes()->push_back(problem.parameters());
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int np = problem_.parameters();
    Eigen::Map<Eigen::VectorXd> out(residuals, np + 1);
    const bool with_jacobian = jacobians != nullptr && jacobians[0] != nullptr;
    VpProblem::Evaluation& at = at_jacobian_;
    if (!problem_.evaluate(parameters[0], with_jacobian ? at.residual.data() : residual_.data(),
                           with_jacobian ? at.jacobian.data() : nullptr,
                           with_jacobian ? &at.beta : nullptr)) {
      if (with_jacobian) at.theta.resize(0);
      return false;
    }
    out.setZero();
    if (!with_jacobian) {
      out(np) = residual_.norm();
      return true;
    }
    at.theta = Eigen::Map<const Eigen::VectorXd>(parameters[0], np);
    if (!compress_least_squares(at.jacobian, at.residual, compressed_)) return false;
    out.head(np) = compressed_.c;
    out(np) = compressed_.s;
    Eigen::Map<RowMajor> jac(jacobians[0], np + 1, np);
    jac.topRows(np) = compressed_.r;
    jac.row(np).setZero();
    return true;
  }
  // The last evaluation with a Jacobian (Ceres asks for the cost alone at trial points, so this is
  // at the last point it accepted), handed over; its theta is empty when there was none.
  VpProblem::Evaluation take_last_jacobian() { return std::move(at_jacobian_); }

 private:
  const VpProblem& problem_;
  mutable Eigen::VectorXd residual_;  // of a cost-only evaluation
  mutable VpProblem::Evaluation at_jacobian_;
  mutable CompressedLeastSquares compressed_;
};

// `problem` evaluated at `theta` with its Jacobian and linear solution: the remembered evaluation
// where its last solve ended (no work), else one computed into `fresh`; null when the model
// cannot be evaluated there.
const VpProblem::Evaluation* evaluated(const VpProblem& problem, const Eigen::VectorXd& theta,
                                       VpProblem::Evaluation& fresh) {
  if (const VpProblem::Evaluation* known = problem.evaluation_at(theta)) return known;
  fresh.theta = theta;
  fresh.residual.resize(problem.residuals());
  fresh.jacobian.resize(problem.residuals(), problem.parameters());
  if (!problem.evaluate(theta.data(), fresh.residual.data(), fresh.jacobian.data(), &fresh.beta))
    return nullptr;
  return &fresh;
}

struct StageOutcome {
  bool usable = false;
  bool converged = false;
  int iterations = 0;
  double cost = 0.0;  // Ceres's final cost, half the sum of squared residuals
  std::string message;
};

StageOutcome solve(const VpProblem& problem, Eigen::VectorXd& theta, int max_iterations) {
  ceres::Problem ceres_problem;
  auto* cost = new VpCost(problem);  // owned by ceres_problem
  ceres_problem.AddResidualBlock(cost, nullptr, theta.data());
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  options.max_num_iterations = max_iterations;
  options.num_threads = 1;  // deterministic and cheap: one dense block
  options.logging_type = ceres::SILENT;
  options.function_tolerance = 1e-10;
  options.parameter_tolerance = 1e-10;
  options.gradient_tolerance = 1e-12;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &ceres_problem, &summary);
  problem.remember(cost->take_last_jacobian());
  StageOutcome out;
  out.usable = summary.IsSolutionUsable();
  out.converged = summary.termination_type == ceres::CONVERGENCE;
  out.iterations = static_cast<int>(summary.iterations.size());
  out.cost = summary.final_cost;
  out.message = summary.message;
  return out;
}

// Matrix pencils of the start: the whole fitted record (constant frequencies and decay rates) and
// sliding init_window_s windows, one per knot spacing, all independent and computed in parallel
// (the results do not depend on the thread count).
struct StartPencils {
  MatrixPencilResult global;
  std::vector<int> first;                  // first sample of each window
  std::vector<MatrixPencilResult> window;  // one per window
  int window_samples = 0;
};

StartPencils start_pencils(const Prepared& p, const UniformCubicBspline& track,
                           const DampedModesOptions& o, int real_poles) {
  const int n = static_cast<int>(p.y.rows());
  StartPencils out;
  out.window_samples =
      std::min(n, std::max(matrix_pencil_min_samples(o.modes, real_poles),
                           static_cast<int>(std::lround(o.init_window_s * p.rate_hz))));
  const int hop = std::max(1, static_cast<int>(std::lround(track.spacing_s() * p.rate_hz)));
  for (int first = 0; first + out.window_samples <= n; first += hop) out.first.push_back(first);
  out.window.resize(out.first.size());
  MatrixPencilOptions po;
  po.modes = o.modes;
  po.real_poles = real_poles;
  po.max_rate_hz = o.init_max_rate_hz;
  data::parallel_for_index(out.first.size() + 1, [&](std::size_t k) {
    if (k == 0) {
      out.global = estimate_matrix_pencil(p.y, p.rate_hz, po);
    } else {
      out.window[k - 1] = estimate_matrix_pencil(
          p.y.middleRows(out.first[k - 1], out.window_samples), p.rate_hz, po);
    }
  });
  return out;
}

// Smooth start for omega_j, alpha_j from the window pencils: each mode's estimates kept where its
// window amplitude-to-noise ratio is at least 6 dB and it continues the previous one, then least
// squares on the spline coefficients with a small first-difference ridge that bridges the gaps
// and holds the ends constant.
Eigen::VectorXd start_tracks(const Prepared& p, const UniformCubicBspline& track,
                             const StartPencils& pencils, const DampedModesOptions& o) {
  const int modes = o.modes;
  const int m = track.size();
  const MatrixPencilResult& global = pencils.global;
  std::vector<std::vector<double>> centre(modes), omega(modes), alpha(modes);
  Eigen::VectorXd last_omega = global.omega_rad_per_s;
  for (std::size_t win = 0; win < pencils.window.size(); ++win) {
    const MatrixPencilResult& w = pencils.window[win];
    const int first = pencils.first[win];
    if (!w.status.ok) continue;
    const double half_s = 0.5 * (pencils.window_samples - 1) / p.rate_hz;
    for (int j = 0; j < modes; ++j) {
      const Eigen::VectorXcd white = p.whiten * w.amplitude.row(j).transpose();
      const double anr = 0.5 * white.squaredNorm() * std::exp(2.0 * w.alpha_per_s(j) * half_s);
      const double ratio = w.omega_rad_per_s(j) / last_omega(j);
      if (anr < 4.0 || ratio < 0.7 || ratio > 1.4 ||
          std::abs(w.alpha_per_s(j)) > w.omega_rad_per_s(j))
        continue;
      // Nearer another mode's track than its own: the window lost mode j (a weak mode in the
      // noise) and its pole j is another mode's.
      bool nearer_other = false;
      for (int i = 0; i < modes; ++i) {
        nearer_other =
            nearer_other || (i != j && std::abs(w.omega_rad_per_s(j) - last_omega(i)) <
                                           std::abs(w.omega_rad_per_s(j) - last_omega(j)));
      }
      if (nearer_other) continue;
      centre[j].push_back(p.tau_s(first) + half_s);
      omega[j].push_back(w.omega_rad_per_s(j));
      alpha[j].push_back(w.alpha_per_s(j));
      last_omega(j) = w.omega_rad_per_s(j);
    }
  }
  Eigen::VectorXd theta(2 * modes * m);
  const Eigen::MatrixXd ridge = 1e-2 * track.first_differences();
  for (int j = 0; j < modes; ++j) {
    if (centre[j].empty()) {
      theta.segment(2 * j * m, m).setConstant(global.alpha_per_s(j));
      theta.segment((2 * j + 1) * m, m).setConstant(global.omega_rad_per_s(j));
      continue;
    }
    const int k = static_cast<int>(centre[j].size());
    const Eigen::MatrixXd b = track.values(Eigen::Map<Eigen::VectorXd>(centre[j].data(), k));
    Eigen::MatrixXd a(k + ridge.rows(), m);
    a << b, ridge;
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(k + ridge.rows(), 2);
    rhs.topLeftCorner(k, 1) = Eigen::Map<Eigen::VectorXd>(alpha[j].data(), k);
    rhs.topRightCorner(k, 1) = Eigen::Map<Eigen::VectorXd>(omega[j].data(), k);
    const Eigen::MatrixXd coef = a.colPivHouseholderQr().solve(rhs);
    theta.segment(2 * j * m, m) = coef.col(0);
    theta.segment((2 * j + 1) * m, m) = coef.col(1);
  }
  return theta;
}

// Roughness prior rows (2 n (M - 2) x P): second differences of every track, row i divided by
// the roughness at its knot, sd(i) (rad/s and 1/s).
Eigen::MatrixXd prior_rows(const UniformCubicBspline& track, int modes, const Eigen::VectorXd& sd) {
  const Eigen::MatrixXd d2 = sd.cwiseInverse().asDiagonal() * track.second_differences();
  const int m = track.size();
  Eigen::MatrixXd rows = Eigen::MatrixXd::Zero(2 * modes * d2.rows(), 2 * modes * m);
  for (int b = 0; b < 2 * modes; ++b) rows.block(b * d2.rows(), b * m, d2.rows(), m) = d2;
  return rows;
}

// One roughness for the whole record: the same SD at every second difference's knot.
Eigen::VectorXd constant_roughness(const UniformCubicBspline& track, double roughness) {
  return Eigen::VectorXd::Constant(track.size() - 2, roughness);
}

// The prior rows with one roughness for the whole record.
Eigen::MatrixXd prior_rows(const UniformCubicBspline& track, int modes, double roughness) {
  return prior_rows(track, modes, constant_roughness(track, roughness));
}

// The linear parameters' design at theta: data rows `a` and shape-penalty rows `r` (without the
// weight). False when the model cannot be evaluated there.
bool linear_design(const VpProblem& problem, const Eigen::VectorXd& theta, Eigen::MatrixXd& a,
                   Eigen::MatrixXd& r) {
  Eigen::MatrixXcd e;
  Eigen::MatrixXd er;
  if (!problem.oscillations(theta.data(), e) || !problem.real_exponentials(theta.data(), er))
    return false;
  problem.design(e, er, a, r);
  return true;
}

// Generalized cross-validation of the shape penalty at fixed tracks (Golub, Heath & Wahba 1979):
// GCV(lambda) = N ||r||^2 / (N - tr H)^2 over a log grid 1e-3 .. 1e6.
double choose_shape_weight(const VpProblem& problem, const Eigen::VectorXd& theta,
                           const Prepared& p) {
  Eigen::MatrixXd a, r;
  if (!linear_design(problem, theta, a, r)) return 1.0;
  const Eigen::MatrixXd ata = a.transpose() * a;
  const Eigen::MatrixXd rtr = r.transpose() * r;
  const Eigen::VectorXd atb = a.transpose() * p.yw;
  const double rows = static_cast<double>(a.rows());
  double best = 1.0, best_score = std::numeric_limits<double>::infinity();
  for (int k = -6; k <= 12; ++k) {
    const double lambda = std::pow(10.0, 0.5 * k);
    const Eigen::MatrixXd normal = ata + lambda * rtr;
    const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(normal);
    const Eigen::VectorXd beta = cod.solve(atb);
    const double trace = effective_parameters(ata, lambda * rtr);
    const double score = rows * (p.yw - a * beta).squaredNorm() / std::pow(rows - trace, 2);
    if (score < best_score) {
      best_score = score;
      best = lambda;
    }
  }
  return best;
}

// Effective number of linear parameters at theta: their count, or with a shape penalty the trace
// of its linear smoother, tr((A^T A + w R^T R)^+ A^T A) (A data rows, R penalty rows).
double linear_effective_parameters(const VpProblem& problem, const Eigen::VectorXd& theta) {
  Eigen::MatrixXd a, r;
  if (problem.penalty_rows() == 0 || !linear_design(problem, theta, a, r)) return problem.linear();
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(a.cols(), a.cols());
  ata.selfadjointView<Eigen::Lower>().rankUpdate(a.transpose());
  return effective_parameters(ata, problem.shape_weight() * (r.transpose() * r));
}

// Effective number of parameters of a fit at theta from its Jacobian there (data rows, then
// prior rows): the trace of the linearized influence of the track coefficients, tr(N^+ Jd^T Jd)
// with N = Jd^T Jd + Jp^T Jp, plus the effective number of linear parameters.
double fit_effective_parameters(const VpProblem& problem, const Eigen::VectorXd& theta,
                                const RowMajor& jacobian) {
  // The tall data rows' product symmetric (lower triangle only).
  const int np = problem.parameters();
  const auto jd = jacobian.topRows(problem.data_rows());
  const auto jp = jacobian.bottomRows(problem.residuals() - problem.data_rows());
  Eigen::MatrixXd data = Eigen::MatrixXd::Zero(np, np);
  data.selfadjointView<Eigen::Lower>().rankUpdate(jd.transpose());
  return effective_parameters(data, jp.transpose() * jp) +
         linear_effective_parameters(problem, theta);
}

// Size of a converged fit: the whitened residual sum of squares of the data rows and, when asked,
// the effective number of parameters (fit_effective_parameters), from one evaluation (none where
// the problem's last solve ended: its remembered Jacobian). False when the model cannot be
// evaluated at theta.
bool fit_size(const VpProblem& problem, const Eigen::VectorXd& theta, bool with_dof, double& rss,
              double& dof) {
  const VpProblem::Evaluation* known = problem.evaluation_at(theta);
  if (!with_dof && !known) {  // the residual alone
    Eigen::VectorXd residual(problem.residuals());
    if (!problem.evaluate(theta.data(), residual.data(), nullptr, nullptr)) return false;
    rss = residual.head(problem.data_rows()).squaredNorm();
    dof = 0.0;
    return true;
  }
  VpProblem::Evaluation fresh;
  const VpProblem::Evaluation* e = known ? known : evaluated(problem, theta, fresh);
  if (e == nullptr) return false;
  rss = e->residual.head(problem.data_rows()).squaredNorm();
  dof = with_dof ? fit_effective_parameters(problem, theta, e->jacobian) : 0.0;
  return true;
}

// True when fit `a` at theta_a has a lower BIC than fit `b` at theta_b, with the residual
// variance unknown: N ln RSS + ln(N) dof, dof the effective parameters of fit_size. The fits need
// not be nested, and on noise-free data both residuals lie far below the whitened noise level
// (the arm's model error), where a variance floored at 1 would prefer the fit with fewer
// parameters however much worse it fits (movement trials, docs/tfa_modal.md).
// `b_size`, when given, is fit b's (RSS, dof) already known from fit_size.
bool lower_bic(const VpProblem& a, const Eigen::VectorXd& theta_a, const VpProblem& b,
               const Eigen::VectorXd& theta_b,
               std::optional<std::pair<double, double>> b_size = std::nullopt) {
  double rss_a = 0.0, dof_a = 0.0, rss_b = 0.0, dof_b = 0.0;
  if (b_size) std::tie(rss_b, dof_b) = *b_size;
  if (!fit_size(a, theta_a, true, rss_a, dof_a) ||
      (!b_size && !fit_size(b, theta_b, true, rss_b, dof_b)))
    return false;
  const double rows = a.data_rows();
  auto sane = [&](double dof) { return std::isfinite(dof) && dof >= 0.0 && dof < rows; };
  auto bic = [&](double rss, double dof) { return rows * std::log(rss) + std::log(rows) * dof; };
  return sane(dof_a) && sane(dof_b) && rss_a > 0.0 && rss_b > 0.0 &&
         bic(rss_a, dof_a) < bic(rss_b, dof_b);
}

// Orthonormal basis (C x C) whose first column is u / |u| (complex Householder completion).
Eigen::MatrixXcd complete_basis(const Eigen::VectorXcd& u) {
  const Eigen::HouseholderQR<Eigen::MatrixXcd> qr(u);
  Eigen::MatrixXcd q = qr.householderQ() * Eigen::MatrixXcd::Identity(u.size(), u.size());
  q.col(0) = u / u.norm();
  return q;
}

// Validity checks against fits the residual cannot tell from good ones: (a) a mode whose power
// exceeds the local whitened data power (+-0.25 s) by more than max_mode_to_data_db: its
// amplitude is cancelled by another mode's (two near-equal tracks with large opposite
// amplitudes, as when a sharp stiffness change outruns the splines); (b) two modes closer in
// frequency than min_mode_separation of their mean or two posterior SDs: merged tracks, whose
// mode shapes and eqs 45-48 are undetermined.
void flag_degenerate_modes(const Prepared& p, const DampedModesOptions& options,
                           std::vector<ModeTrack>& modes) {
  const Eigen::Index n = p.y.rows(), c = p.y.cols();
  Eigen::VectorXd cumulative(n + 1);  // running sum of the whitened data power
  cumulative(0) = 0.0;
  for (Eigen::Index k = 0; k < n; ++k) {
    cumulative(k + 1) = cumulative(k) + p.yw.segment(k * c, c).squaredNorm();
  }
  const Eigen::Index half = std::max<Eigen::Index>(1, std::lround(0.25 * p.rate_hz));
  const double ratio = std::pow(10.0, options.max_mode_to_data_db / 10.0);
  for (ModeTrack& mt : modes) {
    for (Eigen::Index i = 0; i < n; ++i) {
      const Eigen::Index lo = std::max<Eigen::Index>(0, i - half);
      const Eigen::Index hi = std::min<Eigen::Index>(n, i + half + 1);
      const double local = (cumulative(hi) - cumulative(lo)) / static_cast<double>(hi - lo);
      if (std::pow(10.0, mt.anr_db(i) / 10.0) > ratio * local) mt.valid(i) = false;
    }
  }
  for (std::size_t j = 0; j < modes.size(); ++j) {
    for (std::size_t l = j + 1; l < modes.size(); ++l) {
      ModeTrack& a = modes[j];
      ModeTrack& b = modes[l];
      for (Eigen::Index i = 0; i < n; ++i) {
        const double gap = std::abs(a.frequency_hz(i) - b.frequency_hz(i));
        const double limit =
            std::max(options.min_mode_separation * 0.5 * (a.frequency_hz(i) + b.frequency_hz(i)),
                     2.0 * (a.frequency_sd_hz(i) + b.frequency_sd_hz(i)));
        if (!(gap > limit)) a.valid(i) = b.valid(i) = false;
      }
    }
  }
}

// A mode that sinks into the noise before the record ends leaves its tracks to the roughness
// prior there, whose second differences continue them in a straight line from the last bend the
// data made, without bound. From the last sample t0 at which mode j's ANR is at or above
// anr_threshold_db (every later sample below it: the mode has sunk into the noise), omega_j and
// alpha_j (and their slopes, for eqs 45-48) are instead continued as a damped trend: x(t) =
// x(t0) + x'(t0) T (1 - exp(-(t - t0) / T)), T = time_s (0: held), value and slope continuous at
// t0. The samples stay invalid. t0 is set by the ANR, not by the last valid sample: the
// frequency-SD test may flag a sinking mode well above the noise (17 dB, k22_only at 45 degrees
// and 30 dB, where its tracks still followed the data for 0.3 s), and those samples keep the
// tracks the data gave them (flagged). The envelope, phase and ANR stay the fitted model's (a
// mode below the noise: rescaling them by the changed alpha let them grow again, Duffing reach
// trial at 10 dB). A mode whose ANR ends above the threshold (flagged by the other checks:
// merged tracks, model error) keeps its tracks; so does a mode never valid up to t0.
void continue_lost_tracks(const Eigen::VectorXd& t_s, double time_s, double anr_threshold_db,
                          std::vector<ModeTrack>& modes) {
  const Eigen::Index n = t_s.size();
  for (ModeTrack& mt : modes) {
    Eigen::Index last = n - 1;
    while (last >= 0 && !(mt.anr_db(last) >= anr_threshold_db)) --last;
    if (last < 0 || last == n - 1 || !mt.valid.head(last + 1).any()) continue;
    const double w0 = mt.omega_rad_per_s(last), w_slope = mt.omega_dot_rad_per_s2(last);
    const double a0 = mt.alpha_per_s(last), a_slope = mt.alpha_dot_per_s2(last);
    for (Eigen::Index i = last + 1; i < n; ++i) {
      const double s = t_s(i) - t_s(last);
      const double decay = time_s > 0.0 ? std::exp(-s / time_s) : 0.0;
      const double rise = time_s * (1.0 - decay);  // int_0^s exp(-u / T) du; 0 when held
      mt.omega_rad_per_s(i) = w0 + w_slope * rise;
      mt.frequency_hz(i) = mt.omega_rad_per_s(i) / (2.0 * M_PI);
      mt.omega_dot_rad_per_s2(i) = w_slope * decay;
      mt.alpha_per_s(i) = a0 + a_slope * rise;
      mt.alpha_dot_per_s2(i) = a_slope * decay;
    }
  }
}

// Posterior covariance of a fit's nonlinear parameters from its residuals and Jacobian at the
// solution: (J^T J)^+ scaled by the reduced chi-square of the data rows when the residual exceeds
// the pre-onset noise (model error or mis-estimated noise), never below it.
Eigen::MatrixXd posterior_covariance(const VpProblem& problem, const Eigen::VectorXd& residual,
                                     const RowMajor& jacobian) {
  const int rows = problem.data_rows();
  const double dof = std::max(1, rows - problem.linear() - problem.parameters());
  const double chi2 = residual.head(rows).squaredNorm() / dof;
  return std::max(1.0, chi2) *
         Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(normal_matrix(jacobian))
             .pseudoInverse();
}

// Both designs' last step: the validity checks the residual cannot make, then the modes in
// ascending mean frequency. Returns the order: position i holds the fit's mode order[i].
std::vector<int> finish_modes(const Prepared& p, const DampedModesOptions& options,
                              std::vector<ModeTrack>& modes) {
  flag_degenerate_modes(p, options, modes);
  std::vector<int> order(modes.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return modes[a].omega_rad_per_s.mean() < modes[b].omega_rad_per_s.mean();
  });
  std::vector<ModeTrack> sorted;
  for (const int j : order) sorted.push_back(std::move(modes[j]));
  modes = std::move(sorted);
  return order;
}

// Rows [first, first + count) of a prepared record, times from its first row.
Prepared slice(const Prepared& p, int first, int count) {
  const int c = static_cast<int>(p.y.cols());
  Prepared w = p;
  w.t_s = p.t_s.segment(first, count);
  w.tau_s = w.t_s.array() - w.t_s(0);
  w.y = p.y.middleRows(first, count);
  w.yw = p.yw.segment(static_cast<Eigen::Index>(first) * c, static_cast<Eigen::Index>(count) * c);
  return w;
}

// Design (a): a fit of its own for the window of sliding_window_s centred on each fitted sample,
// omega_j and alpha_j linear in time within it (coefficients at the centre and slopes), constant
// complex mode shapes, the same real terms as the start; each window starts from the previous
// one's solution (moved by one sample), the first from the window's matrix pencil. No priors:
// each window's estimate is its own. Outputs at the window centres.
DampedModesResult fit_sliding(const Prepared& p, const DampedModesOptions& options,
                              const StartPencils& pencils, int real, DampedModesResult result) {
  const int n = static_cast<int>(p.y.rows());
  const int c = static_cast<int>(p.y.cols());
  const int modes = options.modes;
  const int half = static_cast<int>(std::lround(0.5 * options.sliding_window_s * p.rate_hz));
  const int width = 2 * half + 1;
  const int windows = n - 2 * half;
  const int needed = matrix_pencil_min_samples(modes, real);
  if (windows < 1 || width < needed) {
    throw InputError("modal fit: sliding_window_s = " + number_text(options.sliding_window_s) +
                     " s needs " + std::to_string(std::max(width, needed)) + " samples at " +
                     number_text(p.rate_hz) + " Hz and fewer than the " + std::to_string(n) +
                     " fitted ones");
  }
  const double dt = 1.0 / p.rate_hz, centre = half * dt;
  // Running integrals from the window's first sample of the basis 1, tau - centre (s, s^2).
  const Eigen::VectorXd tau = Eigen::VectorXd::LinSpaced(width, 0.0, (width - 1) * dt);
  Eigen::MatrixXd integrals(width, 2);
  integrals.col(0) = tau;
  integrals.col(1) = 0.5 * ((tau.array() - centre).square() - centre * centre).matrix();
  const Eigen::MatrixXd constant = Eigen::MatrixXd::Ones(width, 1);
  const Eigen::MatrixXd no_prior(0, 4 * modes);
  std::vector<LinearTerm> terms;
  for (int j = 0; j < modes; ++j)
    for (int k = 0; k < c; ++k) terms.push_back({j, Eigen::VectorXcd::Unit(c, k), 0});

  // A window's pencil as a start: its constant rates and frequencies, slopes zero.
  MatrixPencilOptions po;
  po.modes = modes;
  po.real_poles = real;
  po.max_rate_hz = options.init_max_rate_hz;
  auto pencil_start = [&](const MatrixPencilResult& pencil) {
    Eigen::VectorXd start = Eigen::VectorXd::Zero(4 * modes + real);
    for (int j = 0; j < modes; ++j) {
      start(4 * j) = pencil.alpha_per_s(j);
      start(4 * j + 2) = pencil.omega_rad_per_s(j);
    }
    start.tail(real) = pencil.real_rate_per_s;
    return start;
  };
  // The first window's pencil, or the global one if it fails.
  const MatrixPencilResult first = estimate_matrix_pencil(p.y.topRows(width), p.rate_hz, po);
  Eigen::VectorXd theta = pencil_start(first.status.ok ? first : pencils.global);

  result.t_s = p.t_s.segment(half, windows);
  result.data = p.y.middleRows(half, windows);
  result.fitted = Eigen::MatrixXd::Zero(windows, c);
  result.offset_rad = Eigen::VectorXd::Zero(c);  // not fitted by the windows
  result.converged = true;
  std::vector<ModeTrack> tracks(modes);
  for (ModeTrack& mt : tracks) {
    mt.frequency_hz.resize(windows);
    mt.omega_rad_per_s.resize(windows);
    mt.omega_dot_rad_per_s2.resize(windows);
    mt.alpha_per_s.resize(windows);
    mt.alpha_dot_per_s2.resize(windows);
    mt.shape.resize(windows, c);
    mt.envelope.resize(windows, c);
    mt.phase_rad.resize(windows, c);
    mt.log_envelope_rate_per_s.resize(windows, c);
    mt.anr_db.resize(windows);
    mt.frequency_sd_hz.resize(windows);
    mt.alpha_sd_per_s.resize(windows);
    mt.valid.resize(windows);
  }
  int failed = 0;
  double residual_ss = 0.0;
  const Eigen::MatrixXd lower = p.cholesky;
  for (int t = 0; t < windows; ++t) {
    const Prepared w = slice(p, t, width);
    // No offsets: within one window a constant trades with the slow mode's parameters (noise-
    // free spline-exact test: the frequency SDs of the first windows rise past the validity
    // limit); the posture's error is a record-wide constant for the whole-record fit.
    const VpProblem problem(w, modes, integrals, Eigen::MatrixXd(), constant, terms, {}, 0.0,
                            no_prior, TrackTies{}, real, false);
    Eigen::VectorXd candidate = theta;
    StageOutcome o = solve(problem, candidate, options.max_iterations);
    result.iterations += o.iterations;
    // A window whose fit left the previous one's tracks (a frequency moved by more than
    // 0.25 Hz, or is no longer positive) is fitted again from its own matrix pencil, and the
    // better of the two fits kept.
    auto jumped = [&](const Eigen::VectorXd& x) {
      for (int j = 0; j < modes; ++j) {
        if (!(x(4 * j + 2) > 0.0) || std::abs(x(4 * j + 2) - theta(4 * j + 2)) > 2.0 * M_PI * 0.25)
          return true;
      }
      return false;
    };
    if (t > 0 && (!o.usable || jumped(candidate))) {
      const MatrixPencilResult own = estimate_matrix_pencil(w.y, p.rate_hz, po);
      if (own.status.ok) {
        Eigen::VectorXd restart = pencil_start(own);
        const StageOutcome again = solve(problem, restart, options.max_iterations);
        result.iterations += again.iterations;
        if (again.usable && (!o.usable || again.cost < o.cost)) {
          candidate = restart;
          o = again;
        }
      }
    }
    VpProblem::Evaluation fresh;
    const VpProblem::Evaluation* at = o.usable ? evaluated(problem, candidate, fresh) : nullptr;
    const bool ok = at != nullptr;
    if (!ok) {
      ++failed;
      candidate = theta;  // carry the previous window's tracks over this one
    }
    const Eigen::VectorXd& beta = (ok ? *at : fresh).beta;  // read only when ok
    const bool converged = ok && o.converged;
    result.converged = result.converged && converged;
    const Eigen::MatrixXd covariance =
        ok ? posterior_covariance(problem, at->residual, at->jacobian)
           : Eigen::MatrixXd::Zero(problem.parameters(), problem.parameters());
    for (int j = 0; j < modes; ++j) {
      ModeTrack& mt = tracks[j];
      const double a0 = candidate(4 * j), a1 = candidate(4 * j + 1);
      const double w0 = candidate(4 * j + 2), w1 = candidate(4 * j + 3);
      mt.alpha_per_s(t) = a0;
      mt.alpha_dot_per_s2(t) = a1;
      mt.omega_rad_per_s(t) = w0;
      mt.omega_dot_rad_per_s2(t) = w1;
      mt.frequency_hz(t) = w0 / (2.0 * M_PI);
      mt.alpha_sd_per_s(t) = std::sqrt(std::max(0.0, covariance(4 * j, 4 * j)));
      mt.frequency_sd_hz(t) =
          std::sqrt(std::max(0.0, covariance(4 * j + 2, 4 * j + 2))) / (2.0 * M_PI);
      // Whitened amplitude at the centre: c_jk exp(Phi_j(centre)), then channel units.
      Eigen::VectorXcd white = Eigen::VectorXcd::Zero(c);
      if (ok) {
        const Complex phi(a0 * integrals(half, 0) + a1 * integrals(half, 1),
                          w0 * integrals(half, 0) + w1 * integrals(half, 1));
        for (int k = 0; k < c; ++k)
          white(k) = Complex(beta(2 * (j * c + k)), beta(2 * (j * c + k) + 1)) * std::exp(phi);
      }
      const Eigen::VectorXcd amplitude = lower.cast<Complex>() * white;
      mt.anr_db(t) = 10.0 * std::log10(0.5 * white.squaredNorm());
      for (int k = 0; k < c; ++k) {
        mt.envelope(t, k) = std::abs(amplitude(k));
        double phase = std::arg(amplitude(k));
        if (t > 0) {  // continuous: the nearest branch to the previous phase advanced by omega dt
          const double predicted = mt.phase_rad(t - 1, k) + w0 * dt;
          phase += 2.0 * M_PI * std::round((predicted - phase) / (2.0 * M_PI));
        }
        mt.phase_rad(t, k) = phase;
        mt.shape(t, k) = amplitude(k);  // divided by exp(Phi(t)) below
        mt.log_envelope_rate_per_s(t, k) = a0;
        result.fitted(t, k) += amplitude(k).real();
      }
      mt.valid(t) = converged && mt.anr_db(t) >= options.anr_threshold_db &&
                    mt.frequency_sd_hz(t) <= options.max_frequency_sd_hz && w0 > 0.0 &&
                    std::isfinite(a0);
    }
    for (int r = 0; r < real; ++r) {
      const double rate = candidate(4 * modes + r);
      const Eigen::VectorXd b =
          ok ? Eigen::VectorXd(lower * beta.segment(problem.complex_linear() + r * c, c))
             : Eigen::VectorXd::Zero(c);
      result.fitted.row(t) += std::exp(rate * centre) * b.transpose();
      if (t == windows / 2) {  // reported: the middle window's term, moved to t_s[0]
        RealTerm term;
        term.rate_per_s = rate;
        term.rate_sd_per_s = std::sqrt(std::max(0.0, covariance(4 * modes + r, 4 * modes + r)));
        term.amplitude = std::exp(rate * (p.t_s(half) - p.t_s(t))) * b;
        result.real_terms.push_back(std::move(term));
      }
    }
    if (ok) {
      const Eigen::VectorXd misfit =
          p.whiten * (result.data.row(t) - result.fitted.row(t)).transpose();
      residual_ss += misfit.squaredNorm();
    }
    // The next window, one sample later: the centre values move along the slopes.
    theta = candidate;
    for (int j = 0; j < modes; ++j) {
      theta(4 * j) += theta(4 * j + 1) * dt;
      theta(4 * j + 2) += theta(4 * j + 3) * dt;
    }
  }
  // Shapes as in the whole-record design: amplitude over exp(Phi(t)), Phi the running integral
  // (trapezoid) of the centre tracks from the first centre.
  for (ModeTrack& mt : tracks) {
    double re = 0.0, im = 0.0;
    for (int t = 0; t < windows; ++t) {
      if (t > 0) {
        re += 0.5 * dt * (mt.alpha_per_s(t - 1) + mt.alpha_per_s(t));
        im += 0.5 * dt * (mt.omega_rad_per_s(t - 1) + mt.omega_rad_per_s(t));
      }
      mt.shape.row(t) *= std::exp(-Complex(re, im));
    }
  }
  result.residual_rms_whitened = std::sqrt(residual_ss / std::max(1, (windows - failed) * c));
  if (failed > 0) {
    result.status = Status::failure("modal fit (sliding): " + std::to_string(failed) + " of " +
                                    std::to_string(windows) + " windows could not be fitted");
  }
  if (!result.converged) {
    result.warning = "modal fit (sliding): some windows did not converge in " +
                     std::to_string(options.max_iterations) +
                     " iterations; their samples are flagged invalid";
  }
  result.modes = std::move(tracks);
  finish_modes(slice(p, half, windows), options, result.modes);
  return result;
}

// The most real terms the start may take: as given, or 2n when they are chosen from the data.
int max_real_terms(const DampedModesOptions& options) {
  return options.real_terms >= 0 ? options.real_terms : 2 * options.modes;
}

// What both decay models' fits start from: the prepared data, the mass metric at the fitted
// samples and its slope, the track basis, the number of real terms and the matrix pencils (none
// of which depends on options.decay_tracks).
struct Start {
  Prepared p;
  std::vector<Eigen::MatrixXd> metric, metric_dot;  // (C x C) per fitted sample; empty: none
  UniformCubicBspline track;
  int real = 0;
  StartPencils pencils;
};

Start make_start(const Eigen::Ref<const Eigen::MatrixXd>& deviation, double sample_rate_hz,
                 double start_time_s, double onset_s, const DampedModesOptions& options) {
  Prepared p = prepare(deviation, sample_rate_hz, start_time_s, onset_s, options);
  const int n = static_cast<int>(p.y.rows());
  const int c = static_cast<int>(p.y.cols());
  const int modes = options.modes;
  // The mass metric at the fitted samples and its slope (options.mass_metric), checked before
  // the fit.
  const double dt_s = 1.0 / p.rate_hz;
  std::vector<Eigen::MatrixXd> metric, metric_dot;
  if (options.mass_metric) {
    metric = options.mass_metric(p.t_s);
    Eigen::MatrixXd flat(n, c * c);  // row i: metric[i], column-major
    bool sane = static_cast<int>(metric.size()) == n;
    for (int i = 0; sane && i < n; ++i) {
      sane = metric[i].rows() == c && metric[i].cols() == c && metric[i].allFinite();
      if (sane) flat.row(i) = metric[i].reshaped().transpose();
    }
    if (!sane) {
      throw std::invalid_argument("fit_damped_modes: mass_metric must give one finite " +
                                  std::to_string(c) + " x " + std::to_string(c) +
                                  " matrix per fitted time (" + std::to_string(n) + ")");
    }
    const Eigen::MatrixXd flat_dot = central_differences(flat, dt_s);
    for (int i = 0; i < n; ++i) metric_dot.push_back(flat_dot.row(i).reshaped(c, c));
  }

  UniformCubicBspline track(p.tau_s(n - 1), options.knot_spacing_s);
  // Real terms: as given, or the fewest (0 .. 2n) with which the global pencil finds the n
  // oscillatory poles and the real ones (docs/tfa_modal.md, "Real terms").
  const int max_real = max_real_terms(options);
  int real = std::max(0, options.real_terms);
  if (matrix_pencil_min_samples(modes, real) > n) {
    throw InputError("modal fit: real_terms (--real-terms) " + std::to_string(real) + " with " +
                     std::to_string(modes) + " modes needs at least " +
                     std::to_string(matrix_pencil_min_samples(modes, real)) +
                     " fitted samples; the record has " + std::to_string(n));
  }
  StartPencils pencils = start_pencils(p, track, options, real);
  while (!pencils.global.status.ok && real < max_real &&
         matrix_pencil_min_samples(modes, real + 1) <= n)
    pencils = start_pencils(p, track, options, ++real);
  return Start{std::move(p), std::move(metric), std::move(metric_dot), std::move(track),
               real,         std::move(pencils)};
}

// The whole-record fit (ModalDesign::whole) of one decay model from a start: the stages of
// docs/tfa_modal.md in turn (run()), each trying candidate fits and taking or refusing them
// against the fit taken so far (taken_, theta_, outcome_, and its size taken_rss_, taken_dof_).
class WholeFit {
 public:
  // `result` carries what fit_one filled in before the fit (times, data, the start).
  WholeFit(const Start& from, const DampedModesOptions& options, DampedModesResult result);
  DampedModesResult run();

 private:
  // A stage's rule for taking a candidate: its RSS, effective parameters and the BIC price
  // ln(N) s^2 of one effective parameter (take_fit).
  using Accept = std::function<bool(double rss, double dof, double price)>;
  // The linear design of the fits: constant mode shapes (stage 1) or slowly varying ones.
  struct Design {
    Eigen::MatrixXd functions;
    std::vector<LinearTerm> terms;
    std::vector<std::pair<int, int>> pairs;
    double weight = 0.0;
    double phase_factor = 1.0;  // the penalty on the shapes' phase part, relative to weight
  };

  // The problem of design `d` with shape weight `weight`, track prior rows `prior`, ties `ties`
  // and the second-order terms of mode `so_mode` (-1: none).
  VpProblem vp_problem(const Design& d, double weight, const Eigen::MatrixXd& prior,
                       const TrackTies& ties, int so_mode) const {
    return VpProblem(p_, modes_, integrals_, damping_values_, d.functions, d.terms, d.pairs, weight,
                     prior, ties, real_, options_.offsets, so_mode, d.phase_factor);
  }
  // The problem of the current design and second-order terms with the track prior `prior` and
  // ties `ties`.
  std::unique_ptr<VpProblem> current_problem(const Eigen::MatrixXd& prior,
                                             const TrackTies& ties) const {
    return std::make_unique<VpProblem>(vp_problem(design_, design_.weight, prior, ties, so_mode_));
  }

  int strongest_mode() const;
  Eigen::ArrayXXd frequency_tracks(const Eigen::VectorXd& at) const;
  bool spurious(const VpProblem& problem, const Eigen::VectorXd& at) const;
  bool take_fit(std::unique_ptr<VpProblem>& problem, const Eigen::VectorXd& candidate,
                const StageOutcome& o, bool with_dof, bool spurious_fit, const Accept& accept);
  bool try_candidate(double roughness, const TrackTies& candidate_ties, bool with_dof,
                     const Eigen::VectorXd& start, const Accept& accept, bool restart = false,
                     Eigen::VectorXd* skipped = nullptr);
  // The roughness continuation's rule: a rougher fit pays for its extra effective parameters.
  bool rougher(double rss, double dof, double price) const {
    return taken_rss_ - rss > price * (dof - taken_dof_);
  }
  Accept rougher_rule() const {
    return [this](double rss, double dof, double price) { return rougher(rss, dof, price); };
  }
  double gcv_weight(const Design& d, const Eigen::VectorXd& at,
                    const Eigen::VectorXd& roughness) const;
  Design shape_design(const VpProblem& fitted, const Eigen::VectorXd& at,
                      const Eigen::VectorXd& roughness) const;
  bool fit_design(const Design& d, const Eigen::VectorXd& roughness,
                  std::unique_ptr<VpProblem>& into);

  bool roughness_continuation();
  void search_tie(int part, double option);
  void local_roughness();
  void shape_stage();
  void shape_refit();
  void finish();
  // What every mode's report reads from the final fit.
  struct FinalFit {
    explicit FinalFit(const VpProblem& problem) : fp(problem) {}
    const VpProblem& fp;
    Eigen::VectorXd beta;                        // the linear solution
    Eigen::MatrixXcd e;                          // (N x n) exp(Phi_j)
    Eigen::MatrixXd covariance;                  // posterior covariance of theta
    Eigen::MatrixXd slopes, curvatures;          // (N x M) the track basis' derivatives, 1/s, 1/s^2
    Eigen::MatrixXd functions, function_slopes;  // the final terms' time functions, their slopes
  };
  ModeTrack mode_track(int j, const FinalFit& f);

  // Given.
  const Start& from_;
  const DampedModesOptions& options_;
  const Prepared& p_;
  const UniformCubicBspline& track_;
  const int n_, c_, modes_, m_, real_;
  const double length_s_;  // fitted record, s
  const bool shapes_;      // the shape stages run (knot spacing given, C > 1, a long record)
  const Eigen::MatrixXd integrals_, track_values_;
  const Eigen::MatrixXd damping_values_;  // the track values with damping tracks, else empty
  const Eigen::MatrixXd constant_;        // (N x 1) ones: the constant shapes' time function
  const Design constant_design_;          // stage 1: one free amplitude per mode and channel
  std::vector<double> grid_;              // the roughness candidates, smooth -> rough
  Eigen::VectorXd cold_;                  // the start tracks, the continuation's second start

  // The state of the fit.
  DampedModesResult result_;
  Eigen::VectorXd theta_;
  int so_mode_ = -1;  // mode whose second-order terms are fitted, or -1
  Design design_;
  TrackTies ties_;
  std::unique_ptr<VpProblem> taken_;  // the problem of the fit taken (null: none yet)
  StageOutcome outcome_;
  double taken_rss_ = std::numeric_limits<double>::infinity();
  double taken_dof_ = 0.0;
  bool taken_sized_ = false;   // taken_dof_ counted (fit_size with_dof)
  std::size_t chosen_ = 0;     // stage 1's roughness, in grid_
  Eigen::VectorXd smoothest_;  // the smoothest constant-shape fit, where the shape refit starts
  double uniform_roughness_ = 0.0;    // stage 1's roughness (with the ties' resumption)
  Eigen::VectorXd roughness_sd_;      // per knot: the track prior's SDs of the fit taken
  double local_knots_ = 0.0;          // bent knots of the local roughness taken
  std::unique_ptr<VpProblem> final_;  // the problem of the result
};

// Stage 1's linear terms: one free complex amplitude per mode and whitened channel.
std::vector<LinearTerm> constant_shape_terms(int modes, int channels) {
  std::vector<LinearTerm> terms;
  for (int j = 0; j < modes; ++j)
    for (int k = 0; k < channels; ++k) terms.push_back({j, Eigen::VectorXcd::Unit(channels, k), 0});
  return terms;
}

WholeFit::WholeFit(const Start& from, const DampedModesOptions& options, DampedModesResult result)
    : from_(from),
      options_(options),
      p_(from.p),
      track_(from.track),
      n_(static_cast<int>(from.p.y.rows())),
      c_(static_cast<int>(from.p.y.cols())),
      modes_(options.modes),
      m_(from.track.size()),
      real_(from.real),
      length_s_(from.p.tau_s(n_ - 1)),
      shapes_(options.shape_knot_spacing_s > 0.0 && c_ > 1 &&
              length_s_ > options.shape_knot_spacing_s),
      integrals_(from.track.integrals(from.p.tau_s)),
      track_values_(from.track.values(from.p.tau_s)),
      // With damping tracks the problem needs the basis values too (VpProblem).
      damping_values_(result.decay_tracks == DecayTracks::gamma ? track_values_
                                                                : Eigen::MatrixXd()),
      constant_(Eigen::MatrixXd::Ones(n_, 1)),
      constant_design_{constant_, constant_shape_terms(modes_, c_), {}, 0.0},
      result_(std::move(result)) {
  theta_.resize(2 * modes_ * m_ + real_);
  theta_.head(2 * modes_ * m_) = start_tracks(p_, track_, from.pencils, options_);
  theta_.tail(real_) = from.pencils.global.real_rate_per_s;
  cold_ = theta_;
  grid_ = {options_.track_roughness};
  if (options_.track_roughness < 0.0) grid_ = {0.003, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0};
  design_ = constant_design_;
}

// The stages in turn; a failure ends the fit with result_.status set.
DampedModesResult WholeFit::run() {
  if (!roughness_continuation()) {
    result_.status = Status::failure("modal fit: no usable fit even with the smoothest tracks");
    return std::move(result_);
  }
  if (modes_ > 1 && options_.decay_tie != 0.0) search_tie(0, options_.decay_tie);
  if (modes_ > 1 && options_.frequency_tie != 0.0) search_tie(1, options_.frequency_tie);
  result_.decay_tie = ties_[0].sd;
  result_.frequency_tie = ties_[1].sd;
  // A tie leaves fewer effective parameters to each roughness step: the continuation resumes
  // from the chosen roughness.
  const bool any_tie = ties_[0].sd > 0.0 || ties_[1].sd > 0.0;
  for (std::size_t g = chosen_ + 1; any_tie && g < grid_.size(); ++g) {
    if (!try_candidate(grid_[g], ties_, true, theta_, rougher_rule())) break;
    result_.track_roughness = grid_[g];
  }
  uniform_roughness_ = result_.track_roughness;  // stage 1's, for the shape refit
  roughness_sd_ = constant_roughness(track_, uniform_roughness_);
  local_roughness();
  final_ = std::move(taken_);
  shape_stage();
  shape_refit();
  finish();
  return std::move(result_);
}

// The strongest mode at the start (largest whitened amplitude of the linear solution at the
// start tracks), which is offered the second-order terms; -1 when the start does not evaluate.
int WholeFit::strongest_mode() const {
  const VpProblem probe =
      vp_problem(constant_design_, 0.0, prior_rows(track_, modes_, grid_[0]), TrackTies{}, -1);
  Eigen::VectorXd beta0;
  std::vector<double> scratch(probe.residuals());
  int strongest = -1;
  if (probe.evaluate(theta_.data(), scratch.data(), nullptr, &beta0)) {
    double best = -1.0;
    for (int j = 0; j < modes_; ++j) {
      const double a = beta0.segment(2 * j * c_, 2 * c_).norm();
      if (a > best) {
        best = a;
        strongest = j;
      }
    }
  }
  return strongest;
}

// The track basis at the fitted samples (N x M), and omega_j(tau) of every mode at theta `at`
// (samples x modes), rad/s.
Eigen::ArrayXXd WholeFit::frequency_tracks(const Eigen::VectorXd& at) const {
  Eigen::ArrayXXd omega(track_values_.rows(), modes_);
  for (int j = 0; j < modes_; ++j) omega.col(j) = track_values_ * at.segment((2 * j + 1) * m_, m_);
  return omega;
}

// A fit that explains the response with fewer modes than it claims (docs/tfa_modal.md,
// "Merged modes" and "Cancelling modes"):
// - two modes whose frequency tracks agree within min_mode_separation of their mean at every
//   sample are one mode counted twice: a confluent pair (A + B tau) exp(Phi) with large,
//   cancelling amplitudes, not two modes of the arm (the validity checks flag every frame);
// - modes whose parts of the model cancel, their whitened energies over the record adding up to
//   more than kMaxCancellation times that of their sum, are the same with tracks apart (one
//   mode's amplitude change followed by two opposed oscillations);
// - second-order terms whose part of the model has more energy than the mode that carries
//   them are no small distortion of it: they stand in for a mode (the harmonic exp(2 Phi_j) of
//   a spurious mode at half a weak mode's frequency).
// The roughness continuation does not take such a candidate (it skips it), and of its two
// starts the one that is not spurious is preferred; a spurious fit from the continuation's
// start alone gets the start tracks as a second start.
bool WholeFit::spurious(const VpProblem& problem, const Eigen::VectorXd& at) const {
  const Eigen::ArrayXXd omega = frequency_tracks(at);
  for (int j = 0; j < modes_; ++j)
    for (int l = j + 1; l < modes_; ++l) {
      const Eigen::ArrayXd relative_gap =
          (omega.col(j) - omega.col(l)).abs() / (0.5 * (omega.col(j).abs() + omega.col(l).abs()));
      if (relative_gap.maxCoeff() < options_.min_mode_separation) return true;
    }
  VpProblem::PartEnergies energy;
  if (!problem.part_energies(at.data(), energy)) return true;
  if (energy.modes.sum() > kMaxCancellation * energy.sum) return true;
  const int so = problem.second_order_mode();
  return so >= 0 && energy.distortion >= energy.modes(so);
}

// Takes the fit `o` at `candidate` of `problem` (taken_, theta_, outcome_, taken_*) when it is
// usable, not spurious (`spurious_fit`, the caller's test) and, once a fit has been taken,
// `accept` says so for its RSS, effective parameters and the BIC price ln(N) s^2, s^2 = RSS /
// (N - dof), never below 1; false otherwise.
bool WholeFit::take_fit(std::unique_ptr<VpProblem>& problem, const Eigen::VectorXd& candidate,
                        const StageOutcome& o, bool with_dof, bool spurious_fit,
                        const Accept& accept) {
  double rss = 0.0, dof = 0.0;
  if (!o.usable || !fit_size(*problem, candidate, with_dof, rss, dof)) return false;
  if (spurious_fit) return false;
  const double rows = problem->data_rows();
  const double variance = std::max(1.0, rss / std::max(1.0, rows - dof));
  if (taken_ && !accept(rss, dof, std::log(rows) * variance)) return false;
  taken_ = std::move(problem);
  outcome_ = o;
  theta_ = candidate;
  taken_rss_ = rss;
  taken_dof_ = dof;
  taken_sized_ = with_dof;
  return true;
}

// Fits one candidate from `start` (with `restart`, also from the start tracks: the lower cost
// is kept); taken (take_fit) when `accept` says so for its RSS and effective parameters; false
// when it is not usable, spurious or not taken. A usable fit refused as spurious goes to
// `skipped` (when given; emptied otherwise).
bool WholeFit::try_candidate(double roughness, const TrackTies& candidate_ties, bool with_dof,
                             const Eigen::VectorXd& start, const Accept& accept, bool restart,
                             Eigen::VectorXd* skipped) {
  auto problem = current_problem(prior_rows(track_, modes_, roughness), candidate_ties);
  Eigen::VectorXd candidate = start;
  StageOutcome o;
  // Spurious fits (`spurious`) are refused once a fit has been taken (something to fall back
  // on).
  const bool check = taken_ != nullptr;
  auto is_spurious = [&](const StageOutcome& so, const Eigen::VectorXd& at) {
    return check && so.usable && spurious(*problem, at);
  };
  bool candidate_spurious = false;  // is_spurious(o, candidate), once per fit
  // Takes the fit from the start tracks (spurious or not: `other_spurious`) when it is usable
  // and the kept one is not, or is spurious while it is not, or (equally spurious) has the
  // higher cost: the same choice at any thread count (the continuation's on a tie).
  auto take_cold = [&](const StageOutcome& from_cold, const Eigen::VectorXd& other) {
    const bool other_spurious = is_spurious(from_cold, other);
    const bool prefer =
        from_cold.usable &&
        (!o.usable ||
         (candidate_spurious != other_spurious ? candidate_spurious : from_cold.cost < o.cost));
    if (prefer) {
      o = from_cold;
      candidate = other;
      candidate_spurious = other_spurious;
    }
  };
  const bool other_start = start.size() == cold_.size() && start != cold_;
  if (!restart || !other_start) {
    o = solve(*problem, candidate, options_.max_iterations);
    result_.iterations += o.iterations;
    candidate_spurious = is_spurious(o, candidate);
    // A spurious fit from the continuation: the start tracks get their chance.
    if (other_start && candidate_spurious) {
      Eigen::VectorXd other = cold_;
      const StageOutcome from_cold = solve(*problem, other, options_.max_iterations);
      result_.iterations += from_cold.iterations;
      take_cold(from_cold, other);
    }
  } else {
    // Both starts, solved side by side (each with its own problem and work buffers).
    const VpProblem twin(*problem);
    Eigen::VectorXd other = cold_;
    StageOutcome from_cold;
    data::parallel_for_index(2, [&](std::size_t k) {
      if (k == 0)
        o = solve(*problem, candidate, options_.max_iterations);
      else
        from_cold = solve(twin, other, options_.max_iterations);
    });
    result_.iterations += o.iterations + from_cold.iterations;
    candidate_spurious = is_spurious(o, candidate);
    take_cold(from_cold, other);
  }
  if (skipped) *skipped = candidate_spurious ? candidate : Eigen::VectorXd();
  return take_fit(problem, candidate, o, with_dof, candidate_spurious, accept);
}

// Stage 1: constant mode shapes, one free complex amplitude per mode and whitened channel. The
// track roughness is chosen from the data by the rule below, unless given.
// Roughness from the data, along the continuation smooth -> rough (each fit starts from the
// previous one): a rougher fit is taken only while it pays for its extra effective parameters
// by the BIC rule, RSS drop > ln(N) * (added effective parameters) * s^2, with s^2 = RSS / (N -
// effective parameters) of the rougher fit (the residual's own variance, so a pre-onset noise
// level that is off by a few tens of percent does not move the choice), but never below 1, the
// whitened noise level: on noise-free data the residual is the arm's model error, and with the
// former 60 dB noise floor tracks rough enough to chase it made every frame fail the
// frequency-SD validity test (90 deg constant K: K_valid on 0 of 485 frames). Whitened units.
// Once the continuation has taken a fit rougher than the smoothest (from its third candidate
// on), each candidate is also fitted from the start tracks and the lower cost kept: the data
// have said the smooth fits miss something, and a change the smooth tracks could not follow
// (sharp K: x5 within 0.15 s) leaves them in a basin whose phase no local step undoes, which
// the continuation would carry to the roughest candidate (docs/tfa_modal.md, "Two starts").
// The second-order terms are offered at the smoothest roughness, after the fit without them,
// and kept only when they pay for their 3 C parameters by the same rule: on a record where the
// distortion is below the noise they could otherwise trade with a mode that has sunk into it
// (test a_mode_sinking_into_the_noise_is_flagged_invalid).
// False when not even the smoothest candidate gives a usable fit.
bool WholeFit::roughness_continuation() {
  const int so_offer = options_.second_order ? strongest_mode() : -1;
  // A spurious candidate is skipped, not the end of the continuation: smooth tracks that cannot
  // follow a stiffness change may lend a barely excited mode to the strong one's amplitude change
  // (cancelling modes), and the next roughness, from its tracks, may separate them again
  // (docs/tfa_modal.md, "Cancelling modes").
  Eigen::VectorXd start = theta_, skipped;
  const bool with_dof =
      grid_.size() > 1 || options_.decay_tie < 0.0 || options_.frequency_tie < 0.0 || so_offer >= 0;
  for (std::size_t g = 0; g < grid_.size(); ++g) {
    if (!try_candidate(grid_[g], ties_, with_dof, start, rougher_rule(), g >= 2, &skipped)) {
      if (skipped.size() == 0) break;
      start = skipped;
      continue;
    }
    chosen_ = g;
    if (g == 0 && so_offer >= 0) {
      so_mode_ = so_offer;
      if (!try_candidate(grid_[0], ties_, true, theta_, rougher_rule())) so_mode_ = -1;
    }
    if (g == 0) smoothest_ = theta_;
    start = theta_;
  }
  if (!taken_) return false;
  result_.track_roughness = grid_[chosen_];
  return true;
}

// Decay tie (part 0), then frequency tie (part 1) (TrackTie; both opt-in), each its prior SD
// `option`, or, when negative, from the data at the chosen roughness along the continuation
// loose -> tight, 0.3 .. 0.003 (each fit starting from the previous one): a tighter tie is taken
// while the fit it loses stays within what the same rule grants for the effective parameters it
// saves, RSS rise <= ln(N) * (saved effective parameters) * s^2. When the modes' decays
// (frequencies) do not change by a common factor the RSS rises faster and the search stops (no
// tie when even the loosest is refused). The tie's ratios go in after the tracks (the decay
// tie's first).
void WholeFit::search_tie(int part, double option) {
  std::vector<double> tie_grid = {option};
  if (option < 0.0) tie_grid = {0.3, 0.1, 0.03, 0.01, 0.003};
  TrackTies candidate = ties_;
  TrackTie& tie = candidate[part];
  tie.scale.resize(modes_);
  const Eigen::Index before = taken_->first_ratio(part);  // with the ties taken so far
  Eigen::VectorXd tied(theta_.size() + modes_ - 1);
  tied.head(before) = theta_.head(before);
  tied.tail(theta_.size() - before) = theta_.tail(theta_.size() - before);
  for (int j = 0; j < modes_; ++j) {
    const auto coefficients = theta_.segment((2 * j + part) * m_, m_);
    tie.scale(j) = std::max(coefficients.cwiseAbs().mean(), 1e-3);
    if (j > 0) tied(before + j - 1) = coefficients.mean() / theta_.segment(part * m_, m_).mean();
  }
  if (!tied.segment(before, modes_ - 1).allFinite()) tied.segment(before, modes_ - 1).setOnes();
  const Accept tighter = [&](double rss, double dof, double price) {
    return option > 0.0 || rss - taken_rss_ <= price * (taken_dof_ - dof);
  };
  for (const double sd : tie_grid) {
    tie.sd = sd;
    if (!try_candidate(result_.track_roughness, candidate, true,
                       ties_[part].sd > 0.0 ? theta_ : tied, tighter))
      break;
    ties_[part] = tie;
  }
}

// Local roughness: one roughness for the whole record must be as rough as the sharpest bend of
// any track (a stiffness change within 0.15 s), and then lets every track wobble elsewhere.
// When the continuation chose tracks rougher than the smoothest, each knot gets a roughness of
// its own: a Student-t prior (nu = local_roughness_dof, scale s) on the vector of the 2 n
// tracks' second differences at the knot, fitted by EM: sd_i^2 = (nu s^2 + |D_i theta|^2) /
// (nu + 2 n), then the fit with those SDs (from the previous fit), until no sd_i moves by more
// than 5 % (at most 10 sweeps). The scale runs up the grid below stage 1's roughness (each
// from the previous fit) while the same BIC rule, taken both ways, prefers it: rss + price dof
// below the current fit's (first the uniform one). Its dof: the effective parameters at the
// SDs, plus one per bent knot, where the bends exceed the prior's scale (|D_i theta|^2 > nu
// s^2: the data, not the prior, set that SD), a parameter estimated from the data. Without
// that count a smooth change (sigmoid K) takes a local roughness that trades its smooth bend
// for a few kinks (docs/tfa_modal.md, "Local roughness").
void WholeFit::local_roughness() {
  if (!(options_.local_roughness_dof > 0.0 && options_.track_roughness < 0.0 && taken_ &&
        taken_sized_ && uniform_roughness_ > grid_[0]))
    return;
  const Eigen::MatrixXd d2 = track_.second_differences();
  const double nu = options_.local_roughness_dof;
  auto bent_knots = [&](const Eigen::VectorXd& sd, double scale) {
    return static_cast<double>(
        (sd.array().square() * (nu + 2 * modes_) > 2.0 * nu * scale * scale).count());
  };
  auto em_sd = [&](const Eigen::VectorXd& at, double scale) {
    Eigen::VectorXd sd(d2.rows());
    for (Eigen::Index i = 0; i < d2.rows(); ++i) {
      double squares = 0.0;
      for (int b = 0; b < 2 * modes_; ++b)
        squares += std::pow(d2.row(i).dot(at.segment(b * m_, m_)), 2);
      sd(i) = std::sqrt((nu * scale * scale + squares) / (nu + 2 * modes_));
    }
    return sd;
  };
  for (std::size_t g = 0; g < grid_.size() && grid_[g] < uniform_roughness_; ++g) {
    Eigen::VectorXd candidate = theta_;
    Eigen::VectorXd sd = em_sd(candidate, grid_[g]);
    std::unique_ptr<VpProblem> problem;
    StageOutcome o;
    // sd stays the SDs of the last fit (problem) when the sweeps end.
    for (int sweep = 1;; ++sweep) {
      problem = current_problem(prior_rows(track_, modes_, sd), ties_);
      o = solve(*problem, candidate, options_.max_iterations);
      result_.iterations += o.iterations;
      if (!o.usable || sweep == 10) break;
      const Eigen::VectorXd next = em_sd(candidate, grid_[g]);
      const double moved = (next.array() / sd.array()).log().abs().maxCoeff();
      if (moved < std::log(1.05)) break;
      sd = next;
    }
    const double knots = bent_knots(sd, grid_[g]);
    const Accept lower = [&](double rss, double dof, double price) {
      return rss + price * (dof + knots) < taken_rss_ + price * (taken_dof_ + local_knots_);
    };
    if (!take_fit(problem, candidate, o, true, o.usable && spurious(*problem, candidate), lower))
      break;
    local_knots_ = knots;
    roughness_sd_ = sd;
    result_.track_roughness = grid_[g];
  }
  if (result_.track_roughness != uniform_roughness_) {
    result_.roughness_sd = roughness_sd_;
    const Eigen::Index knots = d2.rows();
    result_.roughness_t_s =
        p_.t_s(0) + track_.spacing_s() * Eigen::ArrayXd::LinSpaced(knots, 0.0, knots - 1.0);
  }
}

// GCV's shape weight for design `d` at the tracks `at`.
double WholeFit::gcv_weight(const Design& d, const Eigen::VectorXd& at,
                            const Eigen::VectorXd& roughness) const {
  const VpProblem probe =
      vp_problem(d, 1.0, prior_rows(track_, modes_, roughness), ties_, so_mode_);
  return choose_shape_weight(probe, at, p_);
}

// The shape design of stage 2 from a constant-shape fit: the common amplitude and phase of mode
// j stay with alpha_j, omega_j (eq 47): only the components orthogonal (in whitened space) to
// its fitted shape u_j vary, as cubic splines whose first differences are penalized with the
// weight given or chosen by GCV at the fit's tracks.
WholeFit::Design WholeFit::shape_design(const VpProblem& fitted, const Eigen::VectorXd& at,
                                        const Eigen::VectorXd& roughness) const {
  Eigen::VectorXd beta(fitted.linear());
  std::vector<double> scratch(fitted.residuals());
  fitted.evaluate(at.data(), scratch.data(), nullptr, &beta);
  const UniformCubicBspline shape(length_s_, options_.shape_knot_spacing_s);
  Design d;
  d.functions.resize(n_, 1 + shape.size());
  d.functions << constant_, shape.values(p_.tau_s);
  for (int j = 0; j < modes_; ++j) {
    Eigen::VectorXcd u(c_);
    for (int k = 0; k < c_; ++k) u(k) = Complex(beta(2 * (j * c_ + k)), beta(2 * (j * c_ + k) + 1));
    if (!(u.norm() > 0.0)) u = Eigen::VectorXcd::Unit(c_, 0);
    Eigen::MatrixXcd basis = complete_basis(u);
    // Each varying direction turned so that a real coefficient changes the shape in phase
    // with u (amplitude ratios: a real rotation of a real shape) and an imaginary one changes
    // the phases between joints: the phase factor penalizes the latter apart. psi makes u
    // most nearly real, u ~ e^{i psi} r (0.5 arg sum u_k^2); likewise for the direction.
    const double psi = 0.5 * std::arg(u.cwiseProduct(u).sum());
    for (int b = 1; b < c_; ++b) {
      const double own = 0.5 * std::arg(basis.col(b).cwiseProduct(basis.col(b)).sum());
      basis.col(b) *= std::polar(1.0, psi - own);
    }
    d.terms.push_back({j, basis.col(0), 0});
    for (int b = 1; b < c_; ++b)
      for (int q = 0; q < shape.size(); ++q) {
        if (q > 0)
          d.pairs.emplace_back(static_cast<int>(d.terms.size()) - 1,
                               static_cast<int>(d.terms.size()));
        d.terms.push_back({j, basis.col(b), 1 + q});
      }
  }
  d.phase_factor = options_.shape_phase_factor;
  d.weight = options_.shape_weight >= 0.0 ? options_.shape_weight : gcv_weight(d, at, roughness);
  return d;
}

// Fits design `d` at `roughness` from theta_; when usable, takes it (theta_, outcome_, `into`).
bool WholeFit::fit_design(const Design& d, const Eigen::VectorXd& roughness,
                          std::unique_ptr<VpProblem>& into) {
  auto problem = std::make_unique<VpProblem>(
      vp_problem(d, d.weight, prior_rows(track_, modes_, roughness), ties_, so_mode_));
  Eigen::VectorXd candidate = theta_;
  const StageOutcome o = solve(*problem, candidate, options_.max_iterations);
  result_.iterations += o.iterations;
  if (!o.usable) return false;
  theta_ = candidate;
  outcome_ = o;
  into = std::move(problem);
  return true;
}

// Stage 2: slowly varying mode shapes, at the chosen tracks. With the weight from the data they
// are kept only when they pay for their effective parameters (lower_bic, as the shape refit
// below): the shapes stay put when the data do not ask them to move. GCV's weight alone can
// let them absorb noise (10 dB trials, docs/tfa_modal.md). A weight given is the user's choice.
void WholeFit::shape_stage() {
  if (!(outcome_.usable && shapes_)) return;
  const Design d = shape_design(*final_, theta_, roughness_sd_);
  std::unique_ptr<VpProblem> constant_shapes = std::move(final_);
  const Eigen::VectorXd constant_theta = theta_;
  const StageOutcome constant_outcome = outcome_;
  // The constant-shape fit is the last candidate taken: its size is known when it was counted.
  std::optional<std::pair<double, double>> constant_size;
  if (taken_sized_) constant_size = std::make_pair(taken_rss_, taken_dof_);
  if (fit_design(d, roughness_sd_, final_) &&
      (options_.shape_weight >= 0.0 ||
       lower_bic(*final_, theta_, *constant_shapes, constant_theta, constant_size))) {
    result_.shape_weight = d.weight;
  } else {
    final_ = std::move(constant_shapes);
    theta_ = constant_theta;
    outcome_ = constant_outcome;
  }
}

// Shape refit. Stage 1's continuation runs with constant shapes, so mode shapes that change
// within the trial (only k22 modulated, a rotating stiffness ellipse) can only be followed by
// rougher tracks, which then trade with the shapes (docs/tfa_modal.md, "Shape refit"). When
// it chose tracks rougher than the smoothest, the other explanation is fitted too: the shape
// stage from the smoothest fit, the roughness continuation (same rule) in it up to, not
// including, stage 1's choice, the shape weight re-chosen by GCV at its tracks. It replaces
// the result when its BIC (effective parameters, the shapes' by the trace of their penalized
// smoother) is lower and its frequency tracks do not cross.
void WholeFit::shape_refit() {
  if (!(options_.shape_refit && outcome_.usable && shapes_ && options_.shape_weight < 0.0 &&
        grid_.size() > 1 && smoothest_.size() > 0))
    return;
  // The refit is untied (its start, the smoothest fit, has no ratios): with a tie taken it is
  // the untied explanation by changing shapes, which the BIC then weighs against the tied one.
  const TrackTies kept_ties = ties_;
  ties_ = TrackTies{};
  const VpProblem base = vp_problem(constant_design_, 0.0, prior_rows(track_, modes_, grid_[0]),
                                    TrackTies{}, so_mode_);
  design_ = shape_design(base, smoothest_, constant_roughness(track_, grid_[0]));
  std::unique_ptr<VpProblem> first_problem = std::move(final_);
  const Eigen::VectorXd first_theta = theta_;
  const StageOutcome first_outcome = outcome_;
  taken_.reset();
  taken_rss_ = std::numeric_limits<double>::infinity();
  taken_dof_ = 0.0;
  double refit_roughness = -1.0;
  // Every candidate from two starts (the continuation's fit and the start tracks): the start
  // tracks were not fitted in this design, so they are a start of their own from the first
  // candidate on (stage 1 takes them from the third).
  Eigen::VectorXd refit_start = smoothest_, refit_skipped;  // spurious candidates skipped
  for (std::size_t g = 0; g < grid_.size() && grid_[g] < uniform_roughness_; ++g) {
    if (!try_candidate(grid_[g], ties_, true, refit_start, rougher_rule(), true, &refit_skipped)) {
      if (refit_skipped.size() == 0) break;
      refit_start = refit_skipped;
      continue;
    }
    refit_start = theta_;
    refit_roughness = grid_[g];
  }
  bool take_refit = false;
  // Tracks that cross or come close: on a coupled arm the two frequencies avoid each other.
  // Two modes whose frequencies lie within a quarter of the shape knots' rate, 1 / (4 h),
  // beat with a period of four shape knots or more, which the shape splines follow: one mode
  // with a varying shape then explains both (a crossing is one mode's shape taking over the
  // other's), and the data cannot tell the two explanations apart. Such a refit is not taken.
  const double min_gap_rad_per_s = 2.0 * M_PI / (4.0 * options_.shape_knot_spacing_s);
  auto too_close = [&](const Eigen::VectorXd& at) {
    const Eigen::ArrayXXd omega = frequency_tracks(at);
    for (int j = 0; j < modes_; ++j)
      for (int l = j + 1; l < modes_; ++l) {
        const Eigen::ArrayXd gap = omega.col(j) - omega.col(l);
        if (gap.maxCoeff() > 0.0 && gap.minCoeff() < 0.0) return true;
        if (gap.abs().minCoeff() < min_gap_rad_per_s) return true;
      }
    return false;
  };
  if (taken_) {
    Design again = design_;
    const Eigen::VectorXd refit_sd = constant_roughness(track_, refit_roughness);
    again.weight = gcv_weight(design_, theta_, refit_sd);
    if (again.weight != design_.weight && fit_design(again, refit_sd, taken_))
      design_.weight = again.weight;
    // The first fit's size, its bent knots counted when it has a local roughness.
    std::optional<std::pair<double, double>> first_size;
    double first_rss = 0.0, first_dof = 0.0;
    if (local_knots_ > 0.0 && fit_size(*first_problem, first_theta, true, first_rss, first_dof))
      first_size = std::make_pair(first_rss, first_dof + local_knots_);
    take_refit =
        lower_bic(*taken_, theta_, *first_problem, first_theta, first_size) && !too_close(theta_);
  }
  if (take_refit) {
    final_ = std::move(taken_);
    result_.track_roughness = refit_roughness;
    result_.roughness_sd.resize(0);
    result_.roughness_t_s.resize(0);
    result_.shape_weight = design_.weight;
    result_.shape_refit = true;
    result_.decay_tie = result_.frequency_tie = 0.0;
  } else {
    final_ = std::move(first_problem);
    theta_ = first_theta;
    outcome_ = first_outcome;
    ties_ = kept_ties;
  }
}

// The final evaluation of the fit taken (final_ at theta_) into result_: the residual, BIC and
// posterior covariance, each mode's tracks, shapes, ANR and validity, the real terms, offsets and
// second-order terms, and the fitted response.
void WholeFit::finish() {
  const VpProblem& fp = *final_;
  FinalFit f(fp);
  VpProblem::Evaluation fresh;
  const VpProblem::Evaluation* at = outcome_.usable ? evaluated(fp, theta_, fresh) : nullptr;
  if (at == nullptr) {
    result_.status = Status::failure("modal fit: the fit failed: " + outcome_.message);
    return;
  }
  const Eigen::VectorXd& residual = at->residual;
  const RowMajor& jacobian = at->jacobian;
  f.beta = at->beta;
  result_.converged = outcome_.converged;
  if (!outcome_.converged) {
    result_.warning = "modal fit: no convergence in " + std::to_string(options_.max_iterations) +
                      " iterations (" + outcome_.message + "); every valid flag is false";
  }
  const int rd = fp.data_rows();
  const double rss = residual.head(rd).squaredNorm();
  result_.residual_rms_whitened = std::sqrt(rss / rd);
  // The bent knots of a local roughness count as parameters, as in the continuation's rule.
  result_.effective_parameters = fit_effective_parameters(fp, theta_, jacobian) +
                                 (result_.roughness_sd.size() > 0 ? local_knots_ : 0.0);
  result_.bic =
      rd * std::log(rss) + std::log(static_cast<double>(rd)) * result_.effective_parameters;
  f.covariance = posterior_covariance(fp, residual, jacobian);

  fp.oscillations(theta_.data(), f.e);
  f.slopes = track_.first_derivatives(p_.tau_s);
  f.curvatures = track_.second_derivatives(p_.tau_s);
  // Time functions and their derivatives as used by the final terms.
  f.functions = constant_;
  f.function_slopes = Eigen::MatrixXd::Zero(n_, 1);
  if (fp.terms().size() != static_cast<size_t>(modes_ * c_) || fp.penalty_rows() > 0) {
    const UniformCubicBspline shape(length_s_, options_.shape_knot_spacing_s);
    f.functions.resize(n_, 1 + shape.size());
    f.functions << constant_, shape.values(p_.tau_s);
    f.function_slopes.resize(n_, 1 + shape.size());
    f.function_slopes << Eigen::MatrixXd::Zero(n_, 1), shape.first_derivatives(p_.tau_s);
  }
  result_.fitted = Eigen::MatrixXd::Zero(n_, c_);
  for (int j = 0; j < modes_; ++j) result_.modes.push_back(mode_track(j, f));
  // Real terms: whitened amplitudes b_r back to channel units L b_r.
  Eigen::MatrixXd er;
  fp.real_exponentials(theta_.data(), er);
  for (int r = 0; r < real_; ++r) {
    RealTerm rt;
    const int index = fp.first_rate() + r;
    rt.rate_per_s = theta_(index);
    rt.rate_sd_per_s = std::sqrt(std::max(0.0, f.covariance(index, index)));
    rt.amplitude = p_.cholesky * f.beta.segment(fp.complex_linear() + r * c_, c_);
    result_.fitted += er.col(r) * rt.amplitude.transpose();
    result_.real_terms.push_back(std::move(rt));
  }
  result_.offset_rad = Eigen::VectorXd::Zero(c_);
  if (fp.first_so() > fp.first_offset()) {  // whitened offsets back to channel units
    result_.offset_rad = p_.cholesky * f.beta.segment(fp.first_offset(), c_);
    result_.fitted.rowwise() += result_.offset_rad.transpose();
  }
  result_.second_order_mode = -1;
  if (fp.second_order_mode() >= 0) {  // the distortion's part of the model, in channel units
    const int j = fp.second_order_mode();
    Eigen::MatrixXd whitened(n_, c_);
    for (Eigen::Index i = 0; i < n_; ++i) {
      const Complex e2 = f.e(i, j) * f.e(i, j);
      for (int k = 0; k < c_; ++k) {
        const int col = fp.first_so() + 3 * k;
        whitened(i, k) = std::norm(f.e(i, j)) * f.beta(col) +
                         (Complex(f.beta(col + 1), f.beta(col + 2)) * e2).real();
      }
    }
    result_.fitted += whitened * p_.cholesky.transpose();
  }
  const std::vector<int> order = finish_modes(p_, options_, result_.modes);
  for (std::size_t i = 0; i < order.size(); ++i)
    if (order[i] == fp.second_order_mode()) result_.second_order_mode = static_cast<int>(i);
  if (options_.lost_track_time_s >= 0.0)
    continue_lost_tracks(result_.t_s, options_.lost_track_time_s, options_.anr_threshold_db,
                         result_.modes);
}

// Mode j of the final fit `f`: its tracks with their SDs, shape, envelopes, phases, ANR and
// validity; adds its part of the model to result_.fitted.
ModeTrack WholeFit::mode_track(int j, const FinalFit& f) {
  const VpProblem& fp = f.fp;
  const Eigen::MatrixXd& values = track_values_;
  const double dt_s = 1.0 / p_.rate_hz;
  ModeTrack mt;
  const Eigen::VectorXd ca = theta_.segment(2 * j * m_, m_),
                        cw = theta_.segment((2 * j + 1) * m_, m_);
  mt.alpha_per_s = values * ca;
  if (j > 0 && ties_[0].sd > 0.0) mt.decay_ratio = theta_(fp.first_ratio(0) + j - 1);
  if (j > 0 && ties_[1].sd > 0.0) mt.frequency_ratio = theta_(fp.first_ratio(1) + j - 1);
  mt.omega_rad_per_s = values * cw;
  mt.alpha_dot_per_s2 = f.slopes * ca;
  mt.omega_dot_rad_per_s2 = f.slopes * cw;
  mt.frequency_hz = mt.omega_rad_per_s / (2.0 * M_PI);
  // d alpha_j(t) / d (decay, frequency coefficients) (T x 2M): the decay coefficients alone, or
  // with damping tracks alpha = a - omega' / (2 omega) (a = -Gamma the spline) also the
  // frequency's, -(B' / (2 omega) - omega' B / (2 omega^2)).
  Eigen::MatrixXd alpha_gradient = Eigen::MatrixXd::Zero(n_, 2 * m_);
  alpha_gradient.leftCols(m_) = values;
  if (fp.damping_tracks()) {
    const Eigen::ArrayXd w = mt.omega_rad_per_s.array(), w_dot = mt.omega_dot_rad_per_s2.array();
    const Eigen::ArrayXd w_ddot = (f.curvatures * cw).array();
    mt.alpha_per_s.array() -= w_dot / (2.0 * w);
    mt.alpha_dot_per_s2.array() -= w_ddot / (2.0 * w) - w_dot.square() / (2.0 * w.square());
    alpha_gradient.rightCols(m_) = -(f.slopes.array().colwise() / (2.0 * w) -
                                     values.array().colwise() * (w_dot / (2.0 * w.square())))
                                        .matrix();
  }
  // Mode j's decay and frequency coefficients are adjacent in theta: one 2M x 2M block.
  const Eigen::MatrixXd cov_aw = f.covariance.block(2 * j * m_, 2 * j * m_, 2 * m_, 2 * m_);
  const Eigen::MatrixXd cov_w = cov_aw.bottomRightCorner(m_, m_);
  mt.alpha_sd_per_s =
      ((alpha_gradient * cov_aw).cwiseProduct(alpha_gradient)).rowwise().sum().cwiseSqrt();
  mt.frequency_sd_hz =
      ((values * cov_w).cwiseProduct(values)).rowwise().sum().cwiseSqrt() / (2.0 * M_PI);
  // Whitened shape w_j(t) and its slope, then channel units a_j = L w_j.
  Eigen::MatrixXcd w = Eigen::MatrixXcd::Zero(n_, c_), w_dot = Eigen::MatrixXcd::Zero(n_, c_);
  for (size_t t = 0; t < fp.terms().size(); ++t) {
    const LinearTerm& term = fp.terms()[t];
    if (term.mode != j) continue;
    const Complex coef(f.beta(2 * t), f.beta(2 * t + 1));
    for (int i = 0; i < n_; ++i) {
      w.row(i) += coef * f.functions(i, term.function) * term.direction.transpose();
      w_dot.row(i) += coef * f.function_slopes(i, term.function) * term.direction.transpose();
    }
  }
  const Eigen::MatrixXcd lower = p_.cholesky.cast<Complex>();
  mt.shape = w * lower.transpose();
  const Eigen::MatrixXcd shape_dot = w_dot * lower.transpose();
  const std::vector<Eigen::MatrixXd>& metric = from_.metric;
  if (!metric.empty()) {
    // The modal coordinate q_j = |a_j|_M e^{Re Phi_j} (docs/tfa_modal.md, "Modal amplitude"):
    // d/dt ln q_j adds Re(a^H M a' + a^H M' a / 2) / |a|_M^2 to alpha_j, and its phase rate
    // Im(a^H M a') / |a|_M^2 (the M-weighted mean of the channels') goes to omega_j.
    Eigen::VectorXd d_alpha(n_), d_omega(n_);
    for (int i = 0; i < n_; ++i) {
      const Eigen::VectorXcd a = mt.shape.row(i).transpose();
      const Eigen::VectorXcd a_dot = shape_dot.row(i).transpose();
      const double norm2 = a.dot(metric[i] * a).real();  // a^H M a, |a|_M^2
      const Complex rate = a.dot(metric[i] * a_dot) + 0.5 * a.dot(from_.metric_dot[i] * a);
      d_alpha(i) = norm2 > 0.0 ? rate.real() / norm2 : 0.0;
      d_omega(i) = norm2 > 0.0 ? rate.imag() / norm2 : 0.0;
    }
    mt.alpha_per_s += d_alpha;
    mt.omega_rad_per_s += d_omega;
    Eigen::MatrixXd corrections(n_, 2);
    corrections << d_alpha, d_omega;
    const Eigen::MatrixXd slopes_of_corrections = central_differences(corrections, dt_s);
    mt.alpha_dot_per_s2 += slopes_of_corrections.col(0);
    mt.omega_dot_rad_per_s2 += slopes_of_corrections.col(1);
    mt.frequency_hz = mt.omega_rad_per_s / (2.0 * M_PI);
  }
  mt.envelope.resize(n_, c_);
  mt.phase_rad.resize(n_, c_);
  mt.log_envelope_rate_per_s.resize(n_, c_);
  mt.anr_db.resize(n_);
  mt.valid.resize(n_);
  const Eigen::VectorXd log_growth = f.e.col(j).cwiseAbs().array().log().matrix();  // Re Phi_j
  const Eigen::VectorXd phase_integral = integrals_ * cw;                           // Im Phi_j
  Eigen::VectorXd shape_phase(c_);
  for (int i = 0; i < n_; ++i) {
    for (int k = 0; k < c_; ++k) {
      const Complex a = mt.shape(i, k);
      mt.envelope(i, k) = std::abs(a) * std::exp(log_growth(i));
      double phase = std::arg(a);  // unwrapped along time: the shape phase varies slowly
      if (i > 0) phase += 2.0 * M_PI * std::round((shape_phase(k) - phase) / (2.0 * M_PI));
      shape_phase(k) = phase;
      mt.phase_rad(i, k) = phase + phase_integral(i);
      mt.log_envelope_rate_per_s(i, k) =
          mt.alpha_per_s(i) +
          (std::norm(a) > 0.0 ? (shape_dot(i, k) * std::conj(a)).real() / std::norm(a) : 0.0);
      result_.fitted(i, k) += (a * f.e(i, j)).real();
    }
    mt.anr_db(i) = 10.0 * std::log10(0.5 * w.row(i).squaredNorm() * std::norm(f.e(i, j)));
    mt.valid(i) = result_.status.ok && result_.converged &&
                  mt.anr_db(i) >= options_.anr_threshold_db &&
                  mt.frequency_sd_hz(i) <= options_.max_frequency_sd_hz &&
                  mt.omega_rad_per_s(i) > 0.0 && std::isfinite(mt.alpha_per_s(i));
  }
  return mt;
}

// One fit from `from` with the decay splines of options.decay_tracks (alpha or gamma; sliding:
// alpha).
DampedModesResult fit_one(const Start& from, const DampedModesOptions& options) {
  const StartPencils& pencils = from.pencils;
  DampedModesResult result;
  result.decay_tracks =
      options.decay_tracks == DecayTracks::gamma && options.design == ModalDesign::whole
          ? DecayTracks::gamma
          : DecayTracks::alpha;
  result.t_s = from.p.t_s;
  result.rate_hz = from.p.rate_hz;
  result.noise_covariance = from.p.noise_cov;
  result.data = from.p.y;
  result.start = pencils.global;
  if (!result.start.status.ok) {
    result.status = Status::failure(
        "modal fit: no start: " + std::to_string(options.modes) +
        " damped oscillations not found in the free response (is the onset the pulse's, and do "
        "the channels respond to it?): " +
        result.start.status.message +
        (options.real_terms < 0
             ? " (also with 1 to " + std::to_string(max_real_terms(options)) + " real terms)"
             : ""));
    return result;
  }
  if (options.design == ModalDesign::sliding)
    return fit_sliding(from.p, options, pencils, from.real, result);
  return WholeFit(from, options, std::move(result)).run();
}

}  // namespace

DampedModesResult fit_damped_modes(const Eigen::Ref<const Eigen::MatrixXd>& deviation,
                                   double sample_rate_hz, double start_time_s, double onset_s,
                                   const DampedModesOptions& options) {
  check_options(options);
  const Start start = make_start(deviation, sample_rate_hz, start_time_s, onset_s, options);
  if (!fits_both_decay_models(options)) return fit_one(start, options);
  // Both decay models from the same start, concurrently (independent fits: the same result at
  // any thread count); the lower BIC wins, alpha on a tie. The two fits have the same spline
  // parameters, but their priors act on different quantities (alpha_j or Gamma_j), so the
  // roughness continuation and the ties spend different effective numbers of them: the
  // residual alone would prefer the more flexible fit (docs/tfa_modal.md, "Choosing the damping
  // tracks by BIC").
  std::array<DampedModesResult, 2> fits;
  data::parallel_for_index(2, [&](std::size_t k) {
    DampedModesOptions o = options;
    o.decay_tracks = k == 0 ? DecayTracks::alpha : DecayTracks::gamma;
    fits[k] = fit_one(start, o);
  });
  constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  // An exact fit (RSS 0) has BIC -inf and wins; NaN (no BIC) never does.
  auto usable = [](const DampedModesResult& f) { return f.status.ok && !std::isnan(f.bic); };
  const bool gamma = usable(fits[1]) && (!usable(fits[0]) || fits[1].bic < fits[0].bic);
  const int iterations = fits[0].iterations + fits[1].iterations;
  std::array<double, 2> rms{nan, nan}, bic{nan, nan};
  for (int k = 0; k < 2; ++k) {
    if (!fits[k].status.ok) continue;
    rms[k] = fits[k].residual_rms_whitened;
    bic[k] = fits[k].bic;
  }
  DampedModesResult result = std::move(fits[gamma ? 1 : 0]);
  result.iterations = iterations;
  result.alpha_residual_rms_whitened = rms[0];
  result.gamma_residual_rms_whitened = rms[1];
  result.alpha_bic = bic[0];
  result.gamma_bic = bic[1];
  return result;
}

RidgeResult as_ridges(const DampedModesResult& result) {
  const int t = static_cast<int>(result.t_s.size());
  const int n = static_cast<int>(result.modes.size());
  RidgeResult r;
  r.time_s = result.t_s;
  r.bin = Eigen::MatrixXi::Constant(t, n, -1);
  r.frequency_hz.resize(t, n);
  r.omega_rad_per_s.resize(t, n);
  r.decay_rate_per_s.resize(t, n);
  for (int j = 0; j < n; ++j) {
    const ModeTrack& m = result.modes[j];
    r.frequency_hz.col(j) = m.frequency_hz;
    r.omega_rad_per_s.col(j) = m.omega_rad_per_s;
    r.decay_rate_per_s.col(j) = m.alpha_per_s;
    r.amplitude.push_back(m.envelope);
    r.phase_rad.push_back(m.phase_rad);
    Eigen::MatrixXcd complex_amplitude(m.envelope.rows(), m.envelope.cols());
    for (Eigen::Index i = 0; i < m.envelope.rows(); ++i)
      for (Eigen::Index k = 0; k < m.envelope.cols(); ++k)
        complex_amplitude(i, k) = std::polar(m.envelope(i, k), m.phase_rad(i, k));
    r.amplitude_c.push_back(std::move(complex_amplitude));
  }
  r.valid.resize(t, n);
  for (int j = 0; j < n; ++j) r.valid.col(j) = result.modes[j].valid;
  r.status = result.status;
  return r;
}

}  // namespace stiffid::estimators
