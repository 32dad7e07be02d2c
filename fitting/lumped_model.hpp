#pragma once
// Lumped viscoelastic models of n degrees of freedom (Piovesan et al. 2012 eqs 14-17), their
// parameter vector, and a fixed-step RK4 simulation templated on the scalar type so that Ceres
// jets give exact derivatives of the simulated outputs with respect to parameters and states.
//
// Models (x, f, q of length n; matrices n x n, symmetric):
//   KV       I x'' + C x' + K x = f                              (eq 15 with the inertia of eq 14)
//   PT       I x'' + KS (x - q) = f,  CP q' = KS (x - q) - KP q   (series KS, parallel KP + CP; eq
//   16) Duffing  I x'' + C x' + K x + B x.^3 = f                     (B diagonal, element-wise
//   cube; eq 17)
//
// Parameterization (vector theta): every symmetric positive definite matrix (I, C, K, KS, KP, CP)
// is A = L L^T with L lower triangular; theta holds L row by row (n (n + 1) / 2 numbers) with the
// diagonal entries stored as log(L_ii), so any real theta gives a symmetric positive definite A and
// every SPD A has exactly one theta. B (Duffing) is diagonal and unconstrained in sign: theta holds
// its n diagonal entries in N/m^3. Units are SI: x in m, f in N, I in kg, C and CP in N s/m, K, KS
// and KP in N/m, B in N/m^3 (or the joint-space analogues rad, N m, kg m^2 ... when x is an angle).

#include <Eigen/Core>
#include <cmath>
#include <string>
#include <vector>

namespace stiffid::fitting {

enum class LumpedModel { kelvin_voigt, poynting_thomson, duffing };
/// Input between samples: first-order hold (linear interpolation) or zero-order hold.
enum class InputHold { first_order, zero_order };

/// "kv" | "pt" | "duffing"; anything else throws InputError naming `what` and the choices.
LumpedModel parse_lumped_model(const std::string& text, const std::string& what = "model");
/// "foh" | "zoh"; anything else throws InputError naming `what`.
InputHold parse_input_hold(const std::string& text, const std::string& what = "--hold");
std::string model_name(LumpedModel model);  ///< "kv" | "pt" | "duffing"

/// One matrix of a model: its name, unit, and how it is parameterized.
struct MatrixParameter {
  std::string name;       ///< "I", "C", "K", "B", "KS", "KP", "CP"
  std::string unit;       ///< SI unit of the entries: "kg", "N s/m", "N/m", "N/m^3"
  bool diagonal = false;  ///< true for B: n free diagonal entries; false: SPD via Cholesky
};

/// The matrices of a model in the order they appear in theta: KV {I, C, K}; PT {I, KS, KP, CP};
/// Duffing {I, C, K, B}.
std::vector<MatrixParameter> model_matrices(LumpedModel model);
/// Number of entries of theta for one matrix of n DOF (n (n + 1) / 2, or n for B).
int matrix_theta_size(const MatrixParameter& matrix, int dof);
/// Length of theta for a model of n DOF.
int theta_size(LumpedModel model, int dof);
/// Length of the simulated state: 2n (x, x') or 3n for PT (x, x', q).
int state_size(LumpedModel model, int dof);

/// theta block of one SPD matrix from the matrix (n x n, symmetric positive definite; an Eigen
/// LLT failure is a broken invariant of the caller).
Eigen::VectorXd spd_to_theta(const Eigen::MatrixXd& a);
/// theta of a whole model from its matrices (in model_matrices order; B given as an n x n
/// diagonal).
Eigen::VectorXd matrices_to_theta(LumpedModel model, const std::vector<Eigen::MatrixXd>& matrices);

/// Dense n x n matrix of scalar type T, at most 8 x 8 on the stack (no heap in the inner loop).
constexpr int kMaxDof = 8;
template <typename T>
using SmallMatrix = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxDof, kMaxDof>;
template <typename T>
using SmallVector = Eigen::Matrix<T, Eigen::Dynamic, 1, 0, kMaxDof, 1>;

/// Matrix of one theta block (see the header comment), n x n.
template <typename T>
SmallMatrix<T> theta_to_matrix(const T* theta, const MatrixParameter& matrix, int n) {
  SmallMatrix<T> out = SmallMatrix<T>::Zero(n, n);
  if (matrix.diagonal) {
    for (int i = 0; i < n; ++i) out(i, i) = theta[i];
    return out;
  }
  SmallMatrix<T> l = SmallMatrix<T>::Zero(n, n);
  int k = 0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j <= i; ++j, ++k) {
      using std::exp;
      l(i, j) = (i == j) ? exp(theta[k]) : theta[k];
    }
  }
  out.noalias() = l * l.transpose();
  return out;
}

/// All matrices of a model from theta, in model_matrices order.
template <typename T>
std::vector<SmallMatrix<T>> theta_to_matrices(const T* theta, LumpedModel model, int n) {
  std::vector<SmallMatrix<T>> out;
  for (const MatrixParameter& m : model_matrices(model)) {
    out.push_back(theta_to_matrix(theta, m, n));
    theta += matrix_theta_size(m, n);
  }
  return out;
}

/// Inverse of a small SPD matrix of scalar type T (Gauss-Jordan without pivoting: valid for SPD).
template <typename T>
SmallMatrix<T> spd_inverse(const SmallMatrix<T>& a) {
  const int n = static_cast<int>(a.rows());
  SmallMatrix<T> m = a;
  SmallMatrix<T> inv = SmallMatrix<T>::Identity(n, n);
  for (int c = 0; c < n; ++c) {
    const T p = T(1.0) / m(c, c);
    m.row(c) *= p;
    inv.row(c) *= p;
    for (int r = 0; r < n; ++r) {
      if (r == c) continue;
      const T factor = m(r, c);
      m.row(r) -= factor * m.row(c);
      inv.row(r) -= factor * inv.row(c);
    }
  }
  return inv;
}

/// The model as a first-order system z' = F(z, f) with z = [x; x'] (or [x; x'; q] for PT), n DOF,
/// precomputed from theta: the products with I^-1 and CP^-1 are formed once per parameter value.
template <typename T>
class LumpedDynamics {
 public:
  LumpedDynamics(const T* theta, LumpedModel model, int n) : model_(model), n_(n) {
    std::vector<SmallMatrix<T>> m = theta_to_matrices(theta, model, n);
    inertia_inverse_ = spd_inverse<T>(m[0]);
    if (model == LumpedModel::poynting_thomson) {
      a_ = inertia_inverse_ * m[1];  // I^-1 KS
      const SmallMatrix<T> cp_inv = spd_inverse<T>(m[3]);
      b_ = cp_inv * m[1];           // CP^-1 KS
      c_ = cp_inv * (m[1] + m[2]);  // CP^-1 (KS + KP)
    } else {
      a_ = inertia_inverse_ * m[2];                                     // I^-1 K
      b_ = inertia_inverse_ * m[1];                                     // I^-1 C
      if (model == LumpedModel::duffing) c_ = inertia_inverse_ * m[3];  // I^-1 B
    }
  }

  int dof() const { return n_; }
  int state_size() const { return model_ == LumpedModel::poynting_thomson ? 3 * n_ : 2 * n_; }
  /// I^-1 f for an input f (N), m/s^2.
  SmallVector<T> accel_of_force(const Eigen::Ref<const Eigen::VectorXd>& f) const {
    return inertia_inverse_ * f.cast<T>();
  }

  /// z' for state z (length state_size()) and input term g = I^-1 f (m/s^2).
  template <typename Z>
  void derivative(const Z& z, const SmallVector<T>& g, SmallVector<T>& dz) const {
    const int n = n_;
    dz.resize(state_size());
    const auto x = z.head(n);
    const auto v = z.segment(n, n);
    dz.head(n) = v;
    if (model_ == LumpedModel::poynting_thomson) {
      const auto q = z.segment(2 * n, n);
      dz.segment(n, n) = g - a_ * (x - q);
      dz.segment(2 * n, n) = b_ * x - c_ * q;
      return;
    }
    dz.segment(n, n) = g - a_ * x - b_ * v;
    if (model_ == LumpedModel::duffing) dz.segment(n, n) -= c_ * x.array().cube().matrix();
  }

 private:
  LumpedModel model_;
  int n_;
  SmallMatrix<T> inertia_inverse_, a_, b_, c_;
};

/// Simulates a model from state z0 over samples [first, last] of an input sequence, with `substeps`
/// classical RK4 steps per sampling interval dt_s; between samples the input is held (ZOH) or
/// linearly interpolated (FOH), so within an interval it is smooth and RK4 keeps its 4th order.
/// `g` holds I^-1 f at each sample (rows = samples, n columns). `emit(i, z)` is called with the
/// state at every sample i in [first, last] (z at sample `first` is z0). Returns the state at
/// sample `last`.
template <typename T, typename Emit>
SmallVector<T> simulate_rk4(const LumpedDynamics<T>& dyn, const std::vector<SmallVector<T>>& g,
                            int first, int last, const SmallVector<T>& z0, double dt_s,
                            int substeps, InputHold hold, Emit&& emit) {
  const int s = dyn.state_size();
  SmallVector<T> z = z0, k1(s), k2(s), k3(s), k4(s), tmp(s);
  const double h = dt_s / substeps;
  emit(first, z);
  for (int i = first; i < last; ++i) {
    const SmallVector<T>& g0 = g[i - first];
    const SmallVector<T>& g1 = g[i - first + 1];
    for (int m = 0; m < substeps; ++m) {
      // fractions of the interval at the start, middle and end of this RK4 step
      const double a0 = static_cast<double>(m) / substeps;
      const double am = (m + 0.5) / substeps;
      const double a1 = static_cast<double>(m + 1) / substeps;
      SmallVector<T> gs, gm, ge;
      if (hold == InputHold::first_order) {
        gs = g0 + (g1 - g0) * T(a0);
        gm = g0 + (g1 - g0) * T(am);
        ge = g0 + (g1 - g0) * T(a1);
      } else {
        gs = g0;
        gm = g0;
        ge = g0;
      }
      dyn.derivative(z, gs, k1);
      tmp = z + k1 * T(0.5 * h);
      dyn.derivative(tmp, gm, k2);
      tmp = z + k2 * T(0.5 * h);
      dyn.derivative(tmp, gm, k3);
      tmp = z + k3 * T(h);
      dyn.derivative(tmp, ge, k4);
      z += (k1 + T(2.0) * (k2 + k3) + k4) * T(h / 6.0);
    }
    emit(i + 1, z);
  }
  return z;
}

}  // namespace stiffid::fitting
