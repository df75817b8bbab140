// The damage equation's finite elements and linear solve, one class for triangles (dim 2) and
// tetrahedra (dim 3): P1 damage on the nodes, assembled in the reference configuration
// (docs/model.md, "Damage"). One implicit step of
//   zeta dd/dt + (s + 2H) d - s l^2 Lap d = 2H        (damage_model.hpp)
// is the symmetric positive definite system
//   [ M (zeta/dt + s + 2H) + s l^2 K ] d+ = M (zeta/dt d + 2H),
// K the P1 stiffness (sum_e V_e grad N_a . grad N_b), M the lumped (row-sum) mass with one value
// of H per element (its reaction and source lumped as V_e / (dim + 1) to each corner), and no flux
// through the boundary. K's sparsity never changes, so the pattern is analysed once: Eigen's
// SimplicialLDLT for small meshes, its ConjugateGradient preconditioned by IncompleteCholesky and
// warm-started from the previous d for large ones. Eigen stays inside damage_solver.cpp.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "solver/damage/damage_model.hpp"
#include "solver/mesh.hpp"
#include "solver/model.hpp"

namespace softshock::damage {

// DamageLinearSolver::kAuto: the direct solver up to this many nodes (docs/performance.md,
// "Phase-field damage": the factorisation's cost against the preconditioned iterations). The
// tetrahedra's factor fills in far more: at 9.4k nodes one direct solve took 0.81 s against 0.074 s
// for conjugate gradients, at 21.8k nodes 6.7 s against 0.2 s; triangles at 33k nodes 0.23 s
// against 0.40 s.
constexpr std::size_t direct_max_nodes(int dim) {
  return dim == 2 ? 40'000 : 5'000;
}

template <int dim>
class DamageSolver {
 public:
  static constexpr int kCorners = dim + 1;
  using Corners = std::array<int32_t, kCorners>;
  using Gradient = std::array<double, dim>;

  struct Report {
    bool direct = true;
    int iterations = 0;   // the iterative solver's (0 for the direct one)
    double residual = 0;  // its relative residual
  };

  // From a finalized mesh of triangles (dim 2) or tetrahedra (dim 3).
  DamageSolver(const Mesh& mesh, const Coefficients& coefficients, DamageLinearSolver kind);
  ~DamageSolver();
  DamageSolver(const DamageSolver&) = delete;
  DamageSolver& operator=(const DamageSolver&) = delete;

  std::size_t node_count() const { return nodal_volume_.size(); }
  std::size_t element_count() const { return corners_.size(); }
  const std::vector<Corners>& corners() const { return corners_; }
  // Reference volume V_e (2-D: area, m^2 per metre of thickness) and the reference gradients of
  // its shape functions, grad N_a (1/m).
  double element_volume(std::size_t e) const { return element_volume_[e]; }
  const Gradient& gradient(std::size_t e, int a) const { return gradient_[e][a]; }
  // The lumped nodal volume V_a = sum over the elements around a of V_e / (dim + 1).
  const std::vector<double>& nodal_volume() const { return nodal_volume_; }
  bool direct() const;

  // A crack already there: these nodes keep d = value (a Dirichlet condition, eliminated
  // symmetrically; the verification's d(0) = 1).
  void fix(std::span<const int32_t> nodes, double value);

  // One step over dt (s; only zeta / dt enters, so any dt > 0 when zeta = 0): d holds the old
  // damage on entry and the new one on return, projected onto [old d, 1] -- the damage never
  // decreases (irreversibility) and never exceeds 1. h_element: H per element (Pa).
  Report solve(std::span<const double> h_element, double dt, std::vector<double>& d);

  // The regularised crack's energy, the integral of s/2 (d^2 + l^2 |grad d|^2) with the lumped
  // mass for d^2 (the functional the solve minimises): J/m in 2-D, J in 3-D.
  double crack_energy(std::span<const double> d) const;

 private:
  struct Impl;
  Coefficients coefficients_;
  std::vector<Corners> corners_;
  std::vector<double> element_volume_;
  std::vector<std::array<Gradient, kCorners>> gradient_;
  std::vector<double> nodal_volume_;
  std::unique_ptr<Impl> impl_;
};

extern template class DamageSolver<2>;
extern template class DamageSolver<3>;

}  // namespace softshock::damage
