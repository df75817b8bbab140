// Model parameters (docs/model.md): Tait + neo-Hookean material, artificial viscosity,
// follower pressure pulse, and the problem a run solves.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "mesh.hpp"

namespace softshock {

struct Material {
  double density_kg_m3 = 1000.0;  // rho0
  double bulk_modulus_Pa = 2e9;   // kappa
  double shear_modulus_Pa = 5e3;  // mu
  double tait_gamma = 6.15;       // gamma-bar; the Tait exponent is n = gamma-bar + 1
  // Kelvin-Voigt shear viscosity eta: Cauchy stress 2 eta dev(D), always on; 0 = elastic. The
  // default is the spec's (docs/model.md, "Physical viscosity"): these structs' defaults are the
  // spec's defaults (run_spec.cpp takes them from here).
  double shear_viscosity_Pa_s = 0.25;
  double tait_n() const { return tait_gamma + 1.0; }
};

// How the artificial viscosity turns on (docs/model.md, "Shock capturing").
enum class ViscositySwitch {
  // Linear term ramps up continuously with the compression measure z = h |dJ/J| / (a dt), full
  // strength from z = ramp; length h from the current area (does not vanish on slivers).
  kContinuous,
  // The thesis: on while J decreases, off otherwise; length h = smallest altitude.
  kCompressionOnly,
};

struct ArtificialViscosity {
  double c1 = 1.0;  // multiplies h * |ln(J+/J)| / dt (compression rate)
  double c2 = 0.1;  // multiplies the acoustic speed
  bool enabled = true;
  ViscositySwitch switch_kind = ViscositySwitch::kContinuous;
  double ramp = 0.2;  // kContinuous: compression measure at which the c2 term is fully on
};

// The volumetric (Tait) response of the triangles (docs/model.md, "Element").
enum class ElementFormulation {
  kP1,                    // one J per element: locks at kappa/mu >> 1
  kAverageNodalPressure,  // Bonet & Burton 1998: J per node from nodal areas, no locking
};

struct Element {
  ElementFormulation formulation = ElementFormulation::kAverageNodalPressure;
  // Weight of the element's own J in the volumetric energy (0 = purely nodal, 1 = plain P1).
  double element_weight = 0.0;
  // beta: stiffness, as a fraction of kappa, against element J departing from the mean of its
  // nodes' (the element-level volume modes nodal pressures leave free; nodal_pressure.hpp).
  // The spec's default (run_spec.cpp); docs/verification.md says why this value.
  double stabilization = 0.01;
  // alpha: weight of the consistent mass in the nodal mass (0 = lumped; default 1, one explicit
  // step towards the consistent mass). The accelerations get one explicit correction towards
  // (1 - alpha) M_L + alpha M_C (integrator.hpp, docs/model.md "Mass blend"; docs/verification.md
  // says why this value).
  double mass_blend = 1.0;
};

// A seeded perturbation of the pulse: p(theta, t) = p(t) (1 + amplitude cos(mode theta)), theta
// the reference polar angle of the loaded edge's midpoint.
struct LoadPerturbation {
  int mode = 0;
  double amplitude = 0.0;
};

enum class PulseShape { kSquare, kGaussian, kLinear, kQuadratic };

// Pressure history p(t) of the follower load (docs/model.md gives each shape).
struct PressurePulse {
  PulseShape shape = PulseShape::kSquare;
  double pressure_Pa = 2e9;
  double duration_s = 8e-9;
  double at(double t_s) const;  // p(t), Pa
  double end_s() const;         // time after which p == 0
  double impulse_Pa_s() const;  // integral of p over time
};

// Phase-field gradient damage (docs/model.md, "Damage"; solver/damage/). Both models solve, in
// the damage d (model 2's c = 1 - d), zeta dd/dt + (s + 2H) d - s l^2 Lap d = 2H with H the
// largest tension-only driving energy so far, and degrade the deviatoric and tensile volumetric
// stress by (1 - d)^2.
enum class DamageModel {
  kNone,        // no damage: the run is exactly the undamaged one
  kTalamini,    // model 1 (Talamini, Mao & Anand 2018): s = eps_f, H above eps_f / 2, viscous
  kGiovanardi,  // model 2 (Giovanardi, Scotti & Formaggia 2017, AT2): s = G / eps, no threshold
};

// How the damage equation's sparse SPD system is solved (damage_solver.hpp).
enum class DamageLinearSolver {
  kAuto,       // direct up to damage::direct_max_nodes(dim) nodes, iterative above
  kDirect,     // Eigen's SimplicialLDLT (pattern analysed once)
  kIterative,  // Eigen's ConjugateGradient with IncompleteCholesky, warm-started from d
};

struct Damage {
  DamageModel model = DamageModel::kNone;
  double length_m = 5e-6;  // l (model 1) or eps (model 2): the regularisation length
  // Model 1: the critical energy density; the threshold is eps_f / 2 and G_c = eps_f l.
  // 2 MPa with l = 5 um is G_c = 10 J/m^2, a brittle hydrogel's (docs/model.md).
  double epsilon_f_Pa = 2e6;
  double fracture_energy_J_m2 = 10.0;  // model 2: G (G_c for a converged sharp crack)
  double zeta_Pa_s = 0.0;              // model 1: the damage viscosity (0: rate independent)
  int update_every = 1;                // N_d: mechanical steps per damage update
  DamageLinearSolver linear_solver = DamageLinearSolver::kAuto;
  bool enabled() const { return model != DamageModel::kNone; }
};

// Everything a run needs besides the numerical options.
struct Problem {
  Mesh mesh;
  Material material;
  ArtificialViscosity viscosity;
  Element element;
  PressurePulse load;
  LoadPerturbation perturbation;
  Damage damage;  // none by default
  // Facets carrying the follower pressure: edges (2-D, body on the left) or faces (3-D,
  // outward); empty = every boundary facet.
  std::vector<std::array<int32_t, 2>> loaded_edges;
  std::vector<std::array<int32_t, 3>> loaded_faces;
  bool load_all_boundary = true;  // false with no loaded facets = no load
  // Per-node velocity constraints (sliding walls, bonded faces): empty = free.
  std::vector<uint8_t> fixed_x, fixed_y, fixed_z;
  // Initial velocity per node, m/s: empty = at rest.
  std::vector<double> initial_vx, initial_vy, initial_vz;
  // Polar frame for diagnostics: origin and R0 (normalises A-bar and modes). Negative R0 =
  // derive: origin = area (volume) centroid, R0 = mean reference distance of the outer boundary
  // nodes (3-D: of the lateral surface, about the z axis through the origin).
  std::array<double, 2> origin{0.0, 0.0};
  double reference_radius_m = -1.0;
  double mid_plane_z_m = 0.0;            // 3-D: the plane of the rim diagnostics and the centre
  bool rim_diagnostics = true;           // 3-D: false = no rim (a body not around the z axis)
  double center_region_radius_m = 5e-6;  // "centre" = elements with centroid this close
};

// The defaults here are also the spec's (run_spec.cpp), but max_aspect_ratio (the spec's is 100).
struct SolverOptions {
  double end_time_s = 800e-9;
  double cfl = 0.75;  // docs/model.md, "Time integration"
  double history_interval_s = 1e-9;
  double output_interval_s = 20e-9;  // <= 0: no field frames
  // Fourier modes 0..modes of the rim radial displacement (fewer on a rim of fewer than
  // 2 modes + 1 nodes: the Diagnostics constructor)
  int modes = 64;
  int threads = 1;        // element-loop threads
  int64_t max_steps = 0;  // 0 = unlimited
  // Fail with FailureKind::kMeshDistortion at the first history sample whose largest element
  // aspect ratio exceeds this; 0 = no limit.
  double max_aspect_ratio = 0;
};

// Origin and R0 of the diagnostics' polar frame: the Problem's own when reference_radius_m > 0,
// else the area centroid and the mean reference distance of the outer boundary nodes.
struct PolarFrame {
  std::array<double, 2> origin;
  double reference_radius_m;
};
PolarFrame polar_frame(const Problem& problem);

}  // namespace softshock
