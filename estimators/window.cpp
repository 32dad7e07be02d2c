#include "estimators/window.hpp"

#include <algorithm>
#include <boost/math/special_functions/bessel.hpp>
#include <cctype>
#include <charconv>
#include <cmath>
#include <sstream>

#include "data/error.hpp"

namespace stiffid::estimators {
namespace {

std::string lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

std::string trim(const std::string& text) {
  const auto first = text.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  const auto last = text.find_last_not_of(" \t");
  return text.substr(first, last - first + 1);
}

// Generalized cosine window a0 - a1 cos(2 pi k / (m - 1)) over m samples (symmetric), written as
// scipy.signal.windows.general_cosine does: a0 + a1 cos(x_k), x_k = -pi + 2 pi k / (m - 1).
double cosine_sample(double a0, double a1, int k, int m) {
  const double step = 2.0 * M_PI / (m - 1);
  return a0 + a1 * std::cos(-M_PI + k * step);
}

}  // namespace

Window Window::kaiser(double beta) {
  if (!std::isfinite(beta) || beta < 0.0 || beta > kMaxKaiserBeta) {
    std::ostringstream msg;
    msg << "kaiser window: beta must be a number in [0, " << kMaxKaiserBeta << "], got " << beta;
    throw InputError(msg.str());
  }
  return Window(Kind::kaiser, beta);
}

Window Window::parse(const std::string& text, const std::string& flag) {
  const std::string t = lower(trim(text));
  if (t == "hann") return hann();
  if (t == "hamming") return hamming();
  if (t == "rect" || t == "rectangular" || t == "boxcar") return rectangular();
  const std::string expected =
      "expected hann, hamming, rect or kaiser:BETA with BETA a number in [0, 700]";
  if (t.rfind("kaiser:", 0) == 0) {
    const std::string number = trim(t.substr(7));
    double beta = 0.0;
    const auto [end, ec] = std::from_chars(number.data(), number.data() + number.size(), beta);
    if (!number.empty() && ec == std::errc() && end == number.data() + number.size() &&
        std::isfinite(beta) && beta >= 0.0 && beta <= kMaxKaiserBeta) {
      return kaiser(beta);
    }
  }
  throw InputError(flag + ": bad window '" + text + "': " + expected);
}

std::string Window::name() const {
  switch (kind_) {
    case Kind::rectangular:
      return "rect";
    case Kind::hann:
      return "hann";
    case Kind::hamming:
      return "hamming";
    case Kind::kaiser: {
      std::ostringstream out;
      out.precision(17);
      out << "kaiser:" << beta_;
      return out.str();
    }
  }
  return "";
}

Eigen::VectorXd Window::samples(int n, WindowSymmetry symmetry) const {
  if (n <= 1) return Eigen::VectorXd::Ones(std::max(n, 0));
  // Periodic = first n samples of the symmetric window of n + 1 (scipy's _extend/_truncate).
  const int m = symmetry == WindowSymmetry::periodic ? n + 1 : n;
  Eigen::VectorXd w(n);
  switch (kind_) {
    case Kind::rectangular:
      w.setOnes();
      break;
    case Kind::hann:
      for (int k = 0; k < n; ++k) w[k] = cosine_sample(0.5, 0.5, k, m);
      break;
    case Kind::hamming:
      for (int k = 0; k < n; ++k) w[k] = cosine_sample(0.54, 0.46, k, m);
      break;
    case Kind::kaiser: {
      const double alpha = (m - 1) / 2.0;
      const double norm = boost::math::cyl_bessel_i(0, beta_);
      for (int k = 0; k < n; ++k) {
        const double r = (k - alpha) / alpha;
        w[k] = boost::math::cyl_bessel_i(0, beta_ * std::sqrt(std::max(0.0, 1.0 - r * r))) / norm;
      }
      break;
    }
  }
  return w;
}

}  // namespace stiffid::estimators
