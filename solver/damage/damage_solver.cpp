#include "solver/damage/damage_solver.hpp"

#include <Eigen/Dense>
#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace softshock::damage {

namespace {

using SparseMatrix = Eigen::SparseMatrix<double, Eigen::ColMajor, int>;
using Vector = Eigen::VectorXd;
// Relative residual of the iterative solve: d is O(1), so 1e-10 is far below any physical
// difference and a few iterations beyond where the warm start leaves it.
constexpr double kIterativeTolerance = 1e-10;

template <int dim>
std::vector<std::array<int32_t, dim + 1>> element_corners(const Mesh& mesh) {
  if constexpr (dim == 2) {
    if (mesh.dimension() != 2) throw std::invalid_argument("damage: a 2-D solver needs triangles");
    return mesh.triangles;
  } else {
    if (mesh.dimension() != 3) throw std::invalid_argument("damage: a 3-D solver needs tetrahedra");
    return mesh.tetrahedra;
  }
}

}  // namespace

template <int dim>
struct DamageSolver<dim>::Impl {
  SparseMatrix stiffness;     // K, both triangles stored (the iterative solver reads both)
  SparseMatrix system;        // the step's matrix, K's pattern
  std::vector<int> diagonal;  // index of (a, a) in the value arrays
  std::vector<uint8_t> fixed;
  std::vector<double> fixed_value;
  bool any_fixed = false;
  bool direct = true;
  Eigen::SimplicialLDLT<SparseMatrix, Eigen::Lower> ldlt;
  Eigen::ConjugateGradient<SparseMatrix, Eigen::Lower | Eigen::Upper,
                           Eigen::IncompleteCholesky<double, Eigen::Lower, Eigen::AMDOrdering<int>>>
      cg;
};

template <int dim>
DamageSolver<dim>::DamageSolver(const Mesh& mesh, const Coefficients& coefficients,
                                DamageLinearSolver kind)
    : coefficients_(coefficients), corners_(element_corners<dim>(mesh)), impl_(new Impl) {
  const std::size_t nn = mesh.node_count(), ne = corners_.size();
  const std::array<const std::vector<double>*, 3> reference = {&mesh.x, &mesh.y, &mesh.z};
  element_volume_.resize(ne);
  gradient_.resize(ne);
  nodal_volume_.assign(nn, 0.0);
  std::vector<Eigen::Triplet<double, int>> entries;
  entries.reserve(ne * kCorners * kCorners);
  const double factorial = dim == 2 ? 2.0 : 6.0;
  for (std::size_t e = 0; e < ne; ++e) {
    const Corners& n = corners_[e];
    Eigen::Matrix<double, dim, dim> dm;  // columns: the reference edges from corner 0
    for (int k = 0; k < dim; ++k)
      for (int c = 0; c < dim; ++c) dm(c, k) = (*reference[c])[n[k + 1]] - (*reference[c])[n[0]];
    const double det = dm.determinant();
    if (!(det > 0)) throw std::invalid_argument("damage: an element of non-positive volume");
    const Eigen::Matrix<double, dim, dim> inverse = dm.inverse();  // rows: grad N_1 .. N_dim
    auto& grad = gradient_[e];
    for (int c = 0; c < dim; ++c) grad[0][c] = 0.0;
    for (int a = 1; a <= dim; ++a)
      for (int c = 0; c < dim; ++c) grad[a][c] = inverse(a - 1, c), grad[0][c] -= inverse(a - 1, c);
    const double volume = det / factorial;
    element_volume_[e] = volume;
    for (int a = 0; a < kCorners; ++a) {
      nodal_volume_[n[a]] += volume / kCorners;
      for (int b = 0; b < kCorners; ++b) {
        double dot = 0.0;
        for (int c = 0; c < dim; ++c) dot += grad[a][c] * grad[b][c];
        entries.emplace_back(n[a], n[b], volume * dot);
      }
    }
  }
  Impl& m = *impl_;
  m.stiffness.resize(static_cast<int>(nn), static_cast<int>(nn));
  m.stiffness.setFromTriplets(entries.begin(), entries.end());
  m.stiffness.makeCompressed();
  m.system = m.stiffness;
  m.diagonal.assign(nn, -1);
  for (int col = 0; col < m.system.outerSize(); ++col)
    for (int k = m.system.outerIndexPtr()[col]; k < m.system.outerIndexPtr()[col + 1]; ++k)
      if (m.system.innerIndexPtr()[k] == col) m.diagonal[col] = k;
  m.fixed.assign(nn, 0);
  m.fixed_value.assign(nn, 0.0);
  m.direct = kind == DamageLinearSolver::kDirect ||
             (kind == DamageLinearSolver::kAuto && nn <= direct_max_nodes(dim));
  // The pattern, once: the fill-reducing ordering and the symbolic factorisation (direct), or the
  // preconditioner's ordering (iterative). Only values change from one step to the next.
  if (m.direct)
    m.ldlt.analyzePattern(m.system);
  else
    m.cg.analyzePattern(m.system), m.cg.setTolerance(kIterativeTolerance);
}

template <int dim>
DamageSolver<dim>::~DamageSolver() = default;

template <int dim>
bool DamageSolver<dim>::direct() const {
  return impl_->direct;
}

template <int dim>
void DamageSolver<dim>::fix(std::span<const int32_t> nodes, double value) {
  for (int32_t i : nodes) {
    impl_->fixed.at(static_cast<std::size_t>(i)) = 1;
    impl_->fixed_value[i] = value;
    impl_->any_fixed = true;
  }
}

template <int dim>
typename DamageSolver<dim>::Report DamageSolver<dim>::solve(std::span<const double> h_element,
                                                            double dt, std::vector<double>& d) {
  Impl& m = *impl_;
  const std::size_t nn = node_count();
  if (h_element.size() != element_count() || d.size() != nn)
    throw std::invalid_argument("damage: H per element and d per node expected");
  const Coefficients& c = coefficients_;
  const double rate = c.zeta_Pa_s > 0 ? c.zeta_Pa_s / dt : 0.0;  // zeta / dt (Pa)
  // Lumped reaction and source: each element's V_e / (dim + 1) of (s + 2H) and 2H to each corner.
  Vector reaction = Vector::Zero(static_cast<int>(nn)), source = Vector::Zero(static_cast<int>(nn));
  for (std::size_t e = 0; e < corners_.size(); ++e) {
    const double share = element_volume_[e] / kCorners, two_h = 2.0 * h_element[e];
    for (int32_t a : corners_[e])
      reaction[a] += share * (c.s_Pa + two_h), source[a] += share * two_h;
  }
  for (std::size_t a = 0; a < nn; ++a) {
    reaction[a] += rate * nodal_volume_[a];
    source[a] += rate * nodal_volume_[a] * d[a];
  }
  // The matrix on K's pattern: s l^2 K plus the reaction on the diagonal.
  const double gradient = c.gradient_N();
  const int nnz = static_cast<int>(m.stiffness.nonZeros());
  const double* k = m.stiffness.valuePtr();
  double* a_values = m.system.valuePtr();
  for (int i = 0; i < nnz; ++i) a_values[i] = gradient * k[i];
  for (std::size_t a = 0; a < nn; ++a) a_values[m.diagonal[a]] += reaction[a];
  // Fixed nodes: row and column eliminated symmetrically (the SPD matrix stays SPD).
  if (m.any_fixed) {
    const int* outer = m.system.outerIndexPtr();
    const int* inner = m.system.innerIndexPtr();
    for (int col = 0; col < static_cast<int>(nn); ++col)
      for (int p = outer[col]; p < outer[col + 1]; ++p) {
        const int row = inner[p];
        if (!m.fixed[row] && !m.fixed[col]) continue;
        if (row == col) {
          a_values[p] = 1.0;
          continue;
        }
        if (m.fixed[col] && !m.fixed[row]) source[row] -= a_values[p] * m.fixed_value[col];
        a_values[p] = 0.0;
      }
    for (std::size_t a = 0; a < nn; ++a)
      if (m.fixed[a]) source[a] = m.fixed_value[a];
  }

  Report report;
  report.direct = m.direct;
  Vector solution;
  if (m.direct) {
    m.ldlt.factorize(m.system);
    if (m.ldlt.info() != Eigen::Success)
      throw std::runtime_error("damage: the LDL^T factorisation failed");
    solution = m.ldlt.solve(source);
  } else {
    m.cg.factorize(m.system);  // the incomplete Cholesky factor of the new values
    const Eigen::Map<const Vector> guess(d.data(), static_cast<int>(nn));
    solution = m.cg.solveWithGuess(source, guess);
    report.iterations = static_cast<int>(m.cg.iterations());
    report.residual = m.cg.error();
    if (m.cg.info() != Eigen::Success)
      throw std::runtime_error("damage: conjugate gradients did not converge (relative residual " +
                               std::to_string(m.cg.error()) + " after " +
                               std::to_string(m.cg.iterations()) + " iterations)");
  }
  // Irreversibility and the upper bound: d+ in [d, 1] (the discrete maximum principle does not
  // hold on every mesh -- obtuse elements -- nor does the gradient term keep d from relaxing).
  for (std::size_t a = 0; a < nn; ++a)
    d[a] = m.fixed[a] ? m.fixed_value[a] : std::clamp(solution[a], d[a], 1.0);
  return report;
}

template <int dim>
double DamageSolver<dim>::crack_energy(std::span<const double> d) const {
  const Eigen::Map<const Vector> field(d.data(), static_cast<int>(d.size()));
  double local = 0.0;
  for (std::size_t a = 0; a < d.size(); ++a) local += nodal_volume_[a] * d[a] * d[a];
  const double gradient = field.dot(impl_->stiffness * field);
  const double l = coefficients_.length_m;
  return 0.5 * coefficients_.s_Pa * (local + l * l * gradient);
}

template class DamageSolver<2>;
template class DamageSolver<3>;

}  // namespace softshock::damage
