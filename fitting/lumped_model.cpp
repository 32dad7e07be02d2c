#include "fitting/lumped_model.hpp"

#include <Eigen/Cholesky>

#include "data/error.hpp"

namespace stiffid::fitting {

LumpedModel parse_lumped_model(const std::string& text, const std::string& what) {
  if (text == "kv") return LumpedModel::kelvin_voigt;
  if (text == "pt") return LumpedModel::poynting_thomson;
  if (text == "duffing") return LumpedModel::duffing;
  throw InputError(what + ": unknown model '" + text + "', expected kv, pt or duffing");
}

InputHold parse_input_hold(const std::string& text, const std::string& what) {
  if (text == "foh") return InputHold::first_order;
  if (text == "zoh") return InputHold::zero_order;
  throw InputError(what + ": unknown hold '" + text + "', expected foh or zoh");
}

std::string model_name(LumpedModel model) {
  switch (model) {
    case LumpedModel::kelvin_voigt:
      return "kv";
    case LumpedModel::poynting_thomson:
      return "pt";
    case LumpedModel::duffing:
      return "duffing";
  }
  return "";
}

std::vector<MatrixParameter> model_matrices(LumpedModel model) {
  switch (model) {
    case LumpedModel::kelvin_voigt:
      return {{"I", "kg", false}, {"C", "N s/m", false}, {"K", "N/m", false}};
    case LumpedModel::poynting_thomson:
      return {
          {"I", "kg", false}, {"KS", "N/m", false}, {"KP", "N/m", false}, {"CP", "N s/m", false}};
    case LumpedModel::duffing:
      return {{"I", "kg", false}, {"C", "N s/m", false}, {"K", "N/m", false}, {"B", "N/m^3", true}};
  }
  return {};
}

int matrix_theta_size(const MatrixParameter& matrix, int dof) {
  return matrix.diagonal ? dof : dof * (dof + 1) / 2;
}

int theta_size(LumpedModel model, int dof) {
  int size = 0;
  for (const MatrixParameter& m : model_matrices(model)) size += matrix_theta_size(m, dof);
  return size;
}

int state_size(LumpedModel model, int dof) {
  return model == LumpedModel::poynting_thomson ? 3 * dof : 2 * dof;
}

Eigen::VectorXd spd_to_theta(const Eigen::MatrixXd& a) {
  const int n = static_cast<int>(a.rows());
  const Eigen::MatrixXd l = a.llt().matrixL();
  Eigen::VectorXd theta(n * (n + 1) / 2);
  int k = 0;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j <= i; ++j, ++k) theta(k) = (i == j) ? std::log(l(i, i)) : l(i, j);
  }
  return theta;
}

Eigen::VectorXd matrices_to_theta(LumpedModel model, const std::vector<Eigen::MatrixXd>& matrices) {
  const std::vector<MatrixParameter> layout = model_matrices(model);
  const int n = static_cast<int>(matrices.front().rows());
  Eigen::VectorXd theta(theta_size(model, n));
  int offset = 0;
  for (std::size_t m = 0; m < layout.size(); ++m) {
    const int size = matrix_theta_size(layout[m], n);
    if (layout[m].diagonal) {
      theta.segment(offset, size) = matrices[m].diagonal();
    } else {
      theta.segment(offset, size) = spd_to_theta(matrices[m]);
    }
    offset += size;
  }
  return theta;
}

}  // namespace stiffid::fitting
