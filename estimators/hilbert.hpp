#pragma once
// Hilbert transform of real signals by FFT (analytic signal z = x + i H[x]).

#include <Eigen/Core>

namespace stiffid::estimators {

/// H[x] for each column of x (S x C): the spectrum is multiplied by -i sign(f) (DC and Nyquist
/// zeroed), after zero padding to a power of two >= 2 S so the transform of the end of the record
/// does not wrap onto its beginning. H[cos(w t)] = sin(w t) for a whole number of periods; near the
/// ends of a finite record the result carries the usual truncation tails. Units of x.
Eigen::MatrixXd hilbert_transform(const Eigen::Ref<const Eigen::MatrixXd>& x);

}  // namespace stiffid::estimators
