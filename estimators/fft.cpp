#include "estimators/fft.hpp"

#include <cassert>
#include <cstring>
#include <mutex>

#include "data/error.hpp"

namespace stiffid::estimators {
namespace {
std::mutex& planner_mutex() {
  static std::mutex m;  // FFTW's planner is not thread-safe; execution with a plan is.
  return m;
}
}  // namespace

RealFft::RealFft(int n, int batch) : n_(n), batch_(batch) {
  if (n < 2 || batch < 1) {
    throw InputError("FFT: length must be >= 2 and batch >= 1, got " + std::to_string(n) + " and " +
                     std::to_string(batch));
  }
  const std::lock_guard<std::mutex> lock(planner_mutex());
  real_ = fftw_alloc_real(static_cast<size_t>(n_) * batch_);
  complex_ = fftw_alloc_complex(static_cast<size_t>(bins()) * batch_);
  std::memset(real_, 0, sizeof(double) * static_cast<size_t>(n_) * batch_);
  // Column-major batches: column c of the real block starts at c*n, of the complex block at c*bins.
  forward_plan_ = fftw_plan_many_dft_r2c(1, &n_, batch_, real_, nullptr, 1, n_, complex_, nullptr,
                                         1, bins(), FFTW_ESTIMATE);
  inverse_plan_ = fftw_plan_many_dft_c2r(1, &n_, batch_, complex_, nullptr, 1, bins(), real_,
                                         nullptr, 1, n_, FFTW_ESTIMATE | FFTW_DESTROY_INPUT);
  assert(forward_plan_ != nullptr && inverse_plan_ != nullptr);
}

RealFft::~RealFft() {
  const std::lock_guard<std::mutex> lock(planner_mutex());
  fftw_destroy_plan(forward_plan_);
  fftw_destroy_plan(inverse_plan_);
  fftw_free(real_);
  fftw_free(complex_);
}

Eigen::MatrixXcd RealFft::forward(const Eigen::Ref<const Eigen::MatrixXd>& x) {
  assert(x.rows() == n_ && x.cols() == batch_);
  Eigen::Map<Eigen::MatrixXd>(real_, n_, batch_) = x;
  fftw_execute(forward_plan_);
  static_assert(sizeof(std::complex<double>) == sizeof(fftw_complex));
  return Eigen::Map<const Eigen::MatrixXcd>(reinterpret_cast<const std::complex<double>*>(complex_),
                                            bins(), batch_);
}

Eigen::MatrixXd RealFft::inverse(const Eigen::Ref<const Eigen::MatrixXcd>& spectrum) {
  assert(spectrum.rows() == bins() && spectrum.cols() == batch_);
  Eigen::Map<Eigen::MatrixXcd>(reinterpret_cast<std::complex<double>*>(complex_), bins(), batch_) =
      spectrum;
  fftw_execute(inverse_plan_);
  return Eigen::Map<const Eigen::MatrixXd>(real_, n_, batch_) / static_cast<double>(n_);
}

}  // namespace stiffid::estimators
