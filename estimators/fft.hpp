#pragma once
// Real-to-complex and complex-to-real FFTs of fixed length over batches of columns, on FFTW.
// Plans are made once per object (FFTW_ESTIMATE, so results are bit-identical run to run and at
// any thread count) and reused for every call. An object is used by one thread at a time; make one
// per thread. Planning is serialized internally, so objects can be built from several threads.

#include <fftw3.h>

#include <Eigen/Core>
#include <complex>

namespace stiffid::estimators {

class RealFft {
 public:
  /// Plans transforms of length `n` (samples) for `batch` columns at once.
  explicit RealFft(int n, int batch = 1);
  ~RealFft();
  RealFft(const RealFft&) = delete;
  RealFft& operator=(const RealFft&) = delete;

  int size() const { return n_; }          ///< transform length n, samples
  int bins() const { return n_ / 2 + 1; }  ///< one-sided bins n/2 + 1
  int batch() const { return batch_; }     ///< columns per call

  /// X[k] = sum_t x[t] exp(-2 pi i k t / n) for each column: (n x batch) -> (bins x batch).
  Eigen::MatrixXcd forward(const Eigen::Ref<const Eigen::MatrixXd>& x);
  /// x[t] = (1/n) sum_k X[k] exp(+2 pi i k t / n) over the full Hermitian spectrum, for each
  /// column: (bins x batch) -> (n x batch). Inverse of forward.
  Eigen::MatrixXd inverse(const Eigen::Ref<const Eigen::MatrixXcd>& spectrum);

  /// In place, without copies: fill the plan's input (column c at input() + c * size()), run
  /// forward_in_place(), read the spectra (column c at output() + c * bins()). Same numbers as
  /// forward().
  double* input() { return real_; }
  void forward_in_place() { fftw_execute(forward_plan_); }
  const std::complex<double>* output() const {
    return reinterpret_cast<const std::complex<double>*>(complex_);
  }

 private:
  int n_;
  int batch_;
  double* real_ = nullptr;
  fftw_complex* complex_ = nullptr;
  fftw_plan forward_plan_ = nullptr;
  fftw_plan inverse_plan_ = nullptr;
};

}  // namespace stiffid::estimators
