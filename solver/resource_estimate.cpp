#include "solver/resource_estimate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "solver/continuum.hpp"
#include "solver/damage/damage_solver.hpp"
#include "solver/integrator.hpp"
#include "solver/tet4_passes.hpp"

namespace softshock {

namespace {

// Measured (docs/deploy.md): ~67 MB fixed, ~0.85 kB per element at peak.
constexpr double kFixedBytes = 67e6;
constexpr double kBytesPerElement = 850;
// History columns besides the modes (time, energies, A-bar, centre/rim figures, dt, the
// Delta-t-setting element, the interval's smallest dt: History::columns()).
constexpr double kHistoryColumns = 20;
// A frame, stored raw (docs/results-format.md): 6 element fields (J, aspect ratio, four
// stresses) and 2 node vectors of 3 columns (nodes ~ elements / 2), doubles; plus the group's
// and its 8 datasets' HDF5 object headers.
constexpr double kFrameBytesPerElement = 6 * 8 + 0.5 * 2 * 3 * 8;
constexpr double kFrameOverheadBytes = 16e3;
// Mesh in the result file: nodes (2 doubles) and triangles (3 int32) per element, roughly.
constexpr double kMeshBytesPerElement = 0.5 * 16 + 12;

// Tetrahedra: softshock-solve's peak resident size (2026-12-05, docs/deploy.md) was 22.6 / 29.6 /
// 67.6 / 189.0 MB at 5,340 / 19,332 / 104,292 / 403,218 tetrahedra of the generated cylinder
// (~20 MB fixed, 400-460 B per tetrahedron; the box alike), and 75.7 / 110.5 MB at 20,250 /
// 105,456 tetrahedra read from a .msh file, which loads Gmsh into the process (~67 MB fixed).
// Taken as 24 MB (70 MB with Gmsh) and 460 B per tetrahedron, plus a frame's fields.
constexpr double kFixedBytes3d = 24e6;
constexpr double kFixedBytes3dWithGmsh = 70e6;
constexpr double kBytesPerTetrahedron = 460;
// Phase-field damage: its matrix, the pattern's analysis and the solver's vectors took +10 / +35 /
// +206 MB at 19k tetrahedra / 66k triangles / 403k tetrahedra (520-530 B per element), taken as
// 600 B; the direct solver's LDLT factor (AUTO: up to direct_max_nodes) another +46 / +131 MB on
// 21.8k / 33.3k-node tetrahedral meshes (~ nodes^2.5; the triangles' factor is within the 600 B).
constexpr double kDamageBytesPerElement = 600;
constexpr double kDamageFactorBytes3d = 55e6;  // at kDamageFactorNodes3d nodes, ~ nodes^2.5
constexpr double kDamageFactorNodes3d = 21800;
constexpr double kNodesPerTetrahedron = 0.22;
constexpr double kFrameBytesPerTetrahedron = 6 * 8 + kNodesPerTetrahedron * 2 * 3 * 8;
// Nodes (3 doubles), tetrahedra (4 int32), boundary faces (3 int32, ~0.1 per tetrahedron).
constexpr double kMeshBytesPerTetrahedron = kNodesPerTetrahedron * 24 + 16 + 0.1 * 12;

// The step's state (ExplicitStep::save_state): a SUCCEEDED job keeps it beside its result for
// ExtendJob, and a running job's checkpoint holds it. Measured 163 B per triangle (nodes ~
// elements / 2) and 179 B per tetrahedron of the meshers' meshes besides the history it carries
// (test_admission, 2026-12-05), taken as 176 and 192 B; with damage also d and its degradation
// per node and H and its degradation per element.
constexpr double kStateBytesPerElement = 176;
constexpr double kStateBytesPerTetrahedron = 192;

// The step model (estimate_steps), fitted per element to the solver's step counts on the first 25
// runs of bench/step_estimate_cases.txt, four to 800 ns and two to 1.6 us, the rest held out
// (docs/reliability.md, "Time steps"): the mean step over dt_load while the shock goes in (the
// pulse and L / U: it converges at the centre, where the step dips to 0.3-0.6 dt_load) and while
// it comes back (L / U);
// after that passage b dt_rest, falling as 1 / (1 + s / tau) with the time s since the passage,
// tau = m 2 L / c0, down to b dt_rest / F (the rim's undulations grow and squeeze its elements:
// the step is near 0.35 dt_rest from ~550 to ~900 ns on the 90 um disk, and recovers to 0.6-0.9
// by 1.6 us). Cylinders with BONDED faces have their own in- and out-going factors and their own
// law after the passage (kBondedCorner).
struct StepFactors {
  double inbound, outbound, after, fall, fall_limit;  // after: b; fall: m (0: none); limit: F
};
constexpr StepFactors kStepFactors2d{1.25, 1.25, 0.99, 3.5, 2.5},
    kStepFactors3d{0.95, 2.0, 0.69, 6.75, 1.5}, kBondedStepFactors3d{0.775, 2.25, 1, 0, 1};
// BONDED cylinders after the passage: the step is set by the rim's element at a corner held by the
// glass, sheared by the rim's outward motion (aspect ratios 10-33; run.max_aspect_ratio stops a
// 32 Pa s pulse's run at 117 ns). The step is dt_rest / (1 + s0 e^(-s / tau)), s the time since
// the passage, recovering over tau = m 2 R / c0, with the corner's shear
//   s0 = k (I / 16 Pa s)^a (T / 20 um)^b (c0 dt_rest / 1.414 um)^c (R / 90 um)^d,
// I = p t_pulse the pulse's impulse, T the layer's thickness, c0 dt_rest the smallest element's
// size as the rest step sees it (finer meshes resolve more of the corner's shear; 1.414 um is the
// default gel's c0 times 1 ns), R the radius. Fitted to the 36 bonded runs of
// bench/step_estimate_cases.txt (thickness 10-75 um, radius 60-120 um, impulse 8-16 Pa s, 10k-105k
// tetrahedra, 200 ns-1 us) to the smallest largest ratio of estimate over steps taken with none
// below 1 (docs/reliability.md, "Time steps").
struct CornerFactors {
  double k, impulse, thickness, element, radius, recovery;
};
constexpr CornerFactors kBondedCorner{2.50, 2.05, 0.86, -0.52, -1.58, 2.86};
// The meshers' smallest and 1st-percentile element altitudes over the mean element's (equilateral
// triangle or regular tetrahedron of the mean area or volume), measured on their meshes
// (docs/reliability.md) and rounded down: concentric rings 0.718 / 0.75 (4k-66k triangles),
// 0.59-0.60 / 0.63 extruded (20k, 100k tetrahedra); Gmsh 0.61 / 0.78 (rounded square), 0.28 /
// 0.50 (cylinder: slivers); the structured corrugated strip 0.75 / 0.75 and box 0.72 / 0.73.
constexpr MeshAltitudes kRingAltitudes2d{0.70, 0.74}, kGmshAltitudes2d{0.55, 0.70},
    kStructuredAltitudes2d{0.72, 0.72}, kRingAltitudes3d{0.57, 0.60}, kGmshAltitudes3d{0.25, 0.45},
    kStructuredAltitudes3d{0.70, 0.70};

bool has_damage(const v1::RunSpec& spec) {
  return spec.has_damage() && spec.damage().model() != v1::NONE &&
         spec.damage().model() != v1::DAMAGE_MODEL_UNSPECIFIED;
}

// The damage's memory (0 without it): per element, and in 3-D the direct solver's factor.
double damage_bytes(const v1::RunSpec& spec, double elements, double nodes, int dim) {
  if (!has_damage(spec)) return 0;
  double bytes = kDamageBytesPerElement * elements;
  const auto solver = spec.damage().linear_solver();
  const bool direct =
      solver == v1::DIRECT || (solver != v1::ITERATIVE && nodes <= damage::direct_max_nodes(dim));
  if (dim == 3 && direct)
    bytes += kDamageFactorBytes3d * std::pow(nodes / kDamageFactorNodes3d, 2.5);
  return bytes;
}

double damage_state_bytes(const v1::RunSpec& spec, double elements, double nodes) {
  return has_damage(spec) ? 16 * (elements + nodes) : 0;
}
// A frame's damage field: d per node (hdf5_support.hpp, kDamageField).
double damage_frame_bytes(const v1::RunSpec& spec, double nodes) {
  return has_damage(spec) ? 8 * nodes : 0;
}

}  // namespace

double spec_area_m2(const v1::RunSpec& spec) {
  const auto& g = spec.geometry();
  if (g.has_disk()) return std::numbers::pi * g.disk().radius() * g.disk().radius();
  if (g.has_rounded_square()) {
    const double side = g.rounded_square().side(), r = g.rounded_square().corner_radius();
    return side * side - (4.0 - std::numbers::pi) * r * r;
  }
  if (g.has_corrugated_strip()) {  // the corrugation's mean over the half wavelength is zero
    return 0.5 * g.corrugated_strip().wavelength() * g.corrugated_strip().height();
  }
  return std::nan("");
}

double spec_volume_m3(const v1::RunSpec& spec) {
  const auto& g = spec.geometry();
  if (g.has_cylinder()) {
    const double r = g.cylinder().radius();
    return std::numbers::pi * r * r * g.cylinder().thickness();
  }
  if (g.has_corrugated_box()) {  // the corrugation's mean is zero for kx, ky > 0; a flat box else
    const auto& b = g.corrugated_box();
    const double mean_top = b.kx() == 0 && b.ky() == 0 ? b.amplitude() : 0.0;
    return b.lx() * b.ly() * (b.lz() + mean_top);
  }
  return std::nan("");
}

namespace {

// The stable step of the smallest element (reference altitude altitude0) in the Tait state at
// `pressure`: J^-n = 1 + n p / kappa, c^2 = (K + 4 mu / 3) J / rho0 (the solver's own laws,
// continuum.hpp), the altitude shortened by J (a shock compresses along its normal). Under the
// load the artificial viscosity inside the front, where the compression measure z (velocity jump
// across an element over the sound speed) stays below ~0.5, adds q ~ c (c2 + c1 z); at rest only
// the physical viscosity 4/3 eta J / (rho0 h) acts. dt = cfl h / (q + sqrt(q^2 + c^2)) times the
// mass blend's factor (continuum::stable_step_sq_kinematic, with the kinematic viscosity q h).
// J^-n of the Tait state at pressure p >= 0: p = (kappa / n)(J^-n - 1).
double tait_j_pow_minus_n(const v1::Material& m, double pressure) {
  return 1.0 + (m.tait_gamma() + 1.0) * std::max(0.0, pressure) / m.bulk_modulus();
}

double stable_dt(const v1::RunSpec& spec, double altitude0, double mass_factor, double pressure,
                 bool shocked) {
  const auto& m = spec.material();
  const double kappa = m.bulk_modulus(), n = m.tait_gamma() + 1.0;
  const double j_minus_n = tait_j_pow_minus_n(m, pressure);
  const double j = std::pow(j_minus_n, -1.0 / n);
  const double bulk = continuum::tait_bulk_modulus(kappa, j_minus_n);
  const double c_sq = continuum::longitudinal_speed_sq(bulk, m.shear_modulus(), m.density(), j);
  const double c = std::sqrt(c_sq);
  const double h = altitude0 * j;
  const double q = (shocked ? c * (spec.viscosity().c2() + 0.5 * spec.viscosity().c1()) : 0.0) +
                   4.0 / 3.0 * m.shear_viscosity() * j / (m.density() * h);
  return spec.run().cfl() * mass_factor *
         std::sqrt(continuum::stable_step_sq_kinematic(h * h, c_sq, q * h));
}

// The longitudinal sound speed at rest, c0.
double rest_wave_speed(const v1::RunSpec& spec) {
  const auto& m = spec.material();
  return std::sqrt(
      continuum::longitudinal_speed_sq(m.bulk_modulus(), m.shear_modulus(), m.density(), 1.0));
}

// The load's shock speed, U^2 = p / (rho0 (1 - J)) (mass and momentum across the front, the
// Tait state behind it); the longitudinal sound speed for a load too weak to compress.
double shock_speed(const v1::RunSpec& spec) {
  const auto& m = spec.material();
  const double p = std::max(0.0, spec.load().pressure());
  const double j = std::pow(tait_j_pow_minus_n(m, p), -1.0 / (m.tait_gamma() + 1.0));
  const double c0 = rest_wave_speed(spec);
  return 1.0 - j > 1e-9 ? std::max(c0, std::sqrt(p / (m.density() * (1.0 - j)))) : c0;
}

// A generated mesh's altitudes over its mean element's.
MeshAltitudes altitude_ratios(const v1::RunSpec& spec, int dim) {
  const auto& g = spec.geometry();
  if (g.has_corrugated_strip()) return kStructuredAltitudes2d;
  if (g.has_corrugated_box()) return kStructuredAltitudes3d;
  const bool rings = g.mesher() == v1::CONCENTRIC_RINGS;
  if (dim == 2) return rings ? kRingAltitudes2d : kGmshAltitudes2d;
  return rings ? kRingAltitudes3d : kGmshAltitudes3d;
}

}  // namespace

double crossing_length_m(const v1::RunSpec& spec) {
  const auto& g = spec.geometry();
  if (g.has_disk()) return g.disk().radius();
  if (g.has_cylinder()) return g.cylinder().radius();
  if (g.has_rounded_square()) return 0.5 * g.rounded_square().side();
  if (g.has_corrugated_strip()) return g.corrugated_strip().height();
  if (g.has_corrugated_box()) return g.corrugated_box().lz();
  return std::nan("");
}

double mesh_crossing_length_m(const Mesh& mesh) {
  double extent = 0;
  for (const auto* c : {&mesh.x, &mesh.y}) {
    if (c->empty()) continue;
    const auto [lo, hi] = std::minmax_element(c->begin(), c->end());
    extent = std::max(extent, *hi - *lo);
  }
  return 0.5 * extent;
}

MeshAltitudes mesh_altitudes(const Mesh& mesh) {
  std::vector<double> altitude_sq;  // per element
  altitude_sq.reserve(mesh.element_count());
  if (mesh.dimension() == 2) {
    for (const auto& t : mesh.triangles) {
      const double e1x = mesh.x[t[1]] - mesh.x[t[0]], e1y = mesh.y[t[1]] - mesh.y[t[0]];
      const double e2x = mesh.x[t[2]] - mesh.x[t[0]], e2y = mesh.y[t[2]] - mesh.y[t[0]];
      altitude_sq.push_back(continuum::smallest_altitude_sq(e1x, e1y, e2x, e2y));
    }
  }
  using Point = std::array<double, 3>;
  auto minus = [](const Point& a, const Point& b) -> Point {
    return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
  };
  auto cross = [](const Point& a, const Point& b) -> Point {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
  };
  auto dot = [](const Point& a, const Point& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; };
  constexpr int kFaces[4][3] = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
  for (const auto& t : mesh.tetrahedra) {  // empty for triangles
    std::array<Point, 4> p;
    for (int a = 0; a < 4; ++a) p[a] = {mesh.x[t[a]], mesh.y[t[a]], mesh.z[t[a]]};
    const double six_volume = dot(cross(minus(p[1], p[0]), minus(p[2], p[0])), minus(p[3], p[0]));
    double largest_face_sq = 0;
    for (const auto& f : kFaces) {
      const Point n = cross(minus(p[f[1]], p[f[0]]), minus(p[f[2]], p[f[0]]));
      largest_face_sq = std::max(largest_face_sq, dot(n, n));
    }
    altitude_sq.push_back(continuum::smallest_altitude_sq(six_volume, largest_face_sq));
  }
  if (altitude_sq.empty()) return {};
  const auto percentile1 =
      altitude_sq.begin() + static_cast<std::ptrdiff_t>(altitude_sq.size() / 100);
  std::nth_element(altitude_sq.begin(), percentile1, altitude_sq.end());
  const double p1 = *percentile1;
  return {std::sqrt(*std::min_element(altitude_sq.begin(), percentile1 + 1)), std::sqrt(p1)};
}

StepEstimate estimate_steps(const v1::RunSpec& spec, const MeshAltitudes& altitudes, int dim,
                            double crossing_length) {
  const double alpha = spec.element().mass_blend();
  const double mass_factor =
      dim == 2 ? mass_blend_step_factor(alpha) : tet4_mass_blend_step_factor(alpha);
  const auto& g = spec.geometry();
  const bool bonded = g.has_cylinder() && g.cylinder().faces() == v1::BONDED;
  const StepFactors factors =
      dim == 2 ? kStepFactors2d : (bonded ? kBondedStepFactors3d : kStepFactors3d);
  StepEstimate e;
  e.dt_rest_s = stable_dt(spec, altitudes.smallest_m, mass_factor, 0.0, false);
  // Many elements are compressed at once: the step follows the compressed step of a low percentile
  // of the altitudes, unless the one smallest element at rest is slower still.
  e.dt_load_s = std::min(e.dt_rest_s, stable_dt(spec, altitudes.percentile1_m, mass_factor,
                                                spec.load().pressure(), true));
  const double pulse = std::max(0.0, spec.load().duration());
  const double crossing_s = crossing_length / shock_speed(spec);
  e.passage_s = pulse + 2.0 * crossing_s;
  const double end = spec.run().end_time();
  const double turn = std::min(end, pulse + crossing_s), passage = std::min(end, e.passage_s);
  const double inbound_dt = std::min(e.dt_rest_s, factors.inbound * e.dt_load_s);
  const double outbound_dt = std::min(e.dt_rest_s, factors.outbound * e.dt_load_s);
  const double after_s = std::max(0.0, end - passage);
  const double c0 = rest_wave_speed(spec);
  double after_steps;
  if (bonded) {
    // The integral of (1 + s0 e^(-s / tau)) / dt_rest over s.
    const auto& k = kBondedCorner;
    const double impulse_Pa_s = std::max(0.0, spec.load().pressure()) * pulse;
    const double s0 = k.k * std::pow(impulse_Pa_s / 16.0, k.impulse) *
                      std::pow(g.cylinder().thickness() / 20e-6, k.thickness) *
                      std::pow(c0 * e.dt_rest_s / 1.414e-6, k.element) *
                      std::pow(crossing_length / 90e-6, k.radius);
    const double tau = k.recovery * 2.0 * crossing_length / c0;
    after_steps = (after_s + s0 * tau * -std::expm1(-after_s / tau)) / e.dt_rest_s;
  } else {
    // The integral of min(F, 1 + s / tau) / (b dt_rest) over s.
    const double fall_s = factors.fall * 2.0 * crossing_length / c0;
    const double falling_s = std::min(after_s, (factors.fall_limit - 1.0) * fall_s);
    after_steps = (fall_s > 0 ? falling_s + 0.5 * falling_s * falling_s / fall_s +
                                    (after_s - falling_s) * factors.fall_limit
                              : after_s) /
                  (factors.after * e.dt_rest_s);
  }
  e.steps = turn / inbound_dt + (passage - turn) / outbound_dt + after_steps;
  // The solver lands exactly on every history sample, on the pulse's end and on every frame: the
  // step before each is cut short, half a step on average where the step varies. That is up to
  // a quarter of the steps of a coarse cylinder whose step is near the 1 ns sample interval.
  const auto& r = spec.run();
  e.steps += 0.5 * std::ceil(end / r.history_interval() - 1e-9);
  if (pulse > 0 && pulse < end) e.steps += 0.5;
  if (r.output_interval() > 0) e.steps += 0.5 * std::floor(end / r.output_interval());
  return e;
}

namespace {

// The steps of a generated mesh's run from its element count (altitudes NaN) or of a given mesh.
StepEstimate steps_for(const v1::RunSpec& spec, int dim, double mean_altitude,
                       MeshAltitudes altitudes, double crossing_length) {
  if (std::isnan(altitudes.smallest_m)) {
    const MeshAltitudes ratio = altitude_ratios(spec, dim);
    altitudes = {ratio.smallest_m * mean_altitude, ratio.percentile1_m * mean_altitude};
  }
  if (std::isnan(crossing_length)) crossing_length = crossing_length_m(spec);
  return estimate_steps(spec, altitudes, dim, crossing_length);
}

}  // namespace

ResourceEstimate estimate_resources(const v1::RunSpec& spec, double elements, double area_m2,
                                    const MeshAltitudes& altitudes, double crossing_length) {
  const auto& r = spec.run();
  ResourceEstimate e;
  // The equilateral triangle of the mean area a has the altitude sqrt(sqrt(3) a).
  const double mean_altitude = std::sqrt(std::sqrt(3.0) * area_m2 / std::max(1.0, elements));
  const StepEstimate steps = steps_for(spec, 2, mean_altitude, altitudes, crossing_length);
  e.dt_s = steps.dt_load_s;
  e.steps = steps.steps;
  const double samples = std::floor(r.end_time() / r.history_interval()) + 1;
  const double history_bytes = samples * (kHistoryColumns + r.modes() + 1) * 8;
  const double frames =
      r.output_interval() > 0 ? std::floor(r.end_time() / r.output_interval()) + 1 : 0;
  // The history is kept while running and copied once when the file is finished.
  e.state_bytes = kStateBytesPerElement * elements + history_bytes +
                  damage_state_bytes(spec, elements, elements / 2);
  // The state is also captured in memory where the run stops (softshockd keeps it).
  e.memory_bytes = kFixedBytes + kBytesPerElement * elements + 2 * history_bytes +
                   kFrameBytesPerElement * elements +
                   damage_bytes(spec, elements, elements / 2, 2) + e.state_bytes;
  e.disk_bytes = frames * (kFrameBytesPerElement * elements + kFrameOverheadBytes +
                           damage_frame_bytes(spec, elements / 2)) +
                 history_bytes + kMeshBytesPerElement * elements + e.state_bytes;
  return e;
}

ResourceEstimate estimate_resources_3d(const v1::RunSpec& spec, double elements, double volume_m3,
                                       const MeshAltitudes& altitudes, double crossing_length) {
  const auto& r = spec.run();
  ResourceEstimate e;
  const double mean_altitude =
      continuum::regular_tetrahedron_altitude(volume_m3 / std::max(1.0, elements));
  const StepEstimate steps = steps_for(spec, 3, mean_altitude, altitudes, crossing_length);
  e.dt_s = steps.dt_load_s;
  e.steps = steps.steps;
  const double samples = std::floor(r.end_time() / r.history_interval()) + 1;
  // The modes twice: at the mid-plane and averaged over the thickness.
  const double history_bytes = samples * (kHistoryColumns + 2 * (r.modes() + 1)) * 8;
  const double frames =
      r.output_interval() > 0 ? std::floor(r.end_time() / r.output_interval()) + 1 : 0;
  const double fixed = !spec.geometry().mesh_file().empty() || !spec.geometry().mesh_id().empty()
                           ? kFixedBytes3dWithGmsh
                           : kFixedBytes3d;
  e.state_bytes = kStateBytesPerTetrahedron * elements + history_bytes +
                  damage_state_bytes(spec, elements, kNodesPerTetrahedron * elements);
  e.memory_bytes = fixed + kBytesPerTetrahedron * elements + 2 * history_bytes +
                   kFrameBytesPerTetrahedron * elements +
                   damage_bytes(spec, elements, kNodesPerTetrahedron * elements, 3) + e.state_bytes;
  e.disk_bytes = frames * (kFrameBytesPerTetrahedron * elements + kFrameOverheadBytes +
                           damage_frame_bytes(spec, kNodesPerTetrahedron * elements)) +
                 history_bytes + kMeshBytesPerTetrahedron * elements + e.state_bytes;
  return e;
}

ResourceEstimate estimate_spec_resources(const v1::RunSpec& spec) {
  const double elements = spec.geometry().target_elements();
  const double volume = spec_volume_m3(spec);
  if (!std::isnan(volume)) return estimate_resources_3d(spec, elements, volume);
  const double area = spec_area_m2(spec);
  if (!std::isnan(area)) return estimate_resources(spec, elements, area);
  const double nan = std::nan("");
  return {nan, nan, nan, nan, nan};
}

namespace {

double crossing_length_of(const v1::RunSpec& spec, const Mesh& mesh) {
  const double crossing = crossing_length_m(spec);
  return std::isnan(crossing) ? mesh_crossing_length_m(mesh) : crossing;
}

}  // namespace

StepEstimate estimate_mesh_steps(const v1::RunSpec& spec, const Mesh& mesh) {
  return estimate_steps(spec, mesh_altitudes(mesh), mesh.dimension(),
                        crossing_length_of(spec, mesh));
}

ResourceEstimate estimate_mesh_resources(const v1::RunSpec& spec, const Mesh& mesh) {
  const double elements = static_cast<double>(mesh.element_count());
  const MeshAltitudes altitudes = mesh_altitudes(mesh);
  const double crossing = crossing_length_of(spec, mesh);
  return mesh.dimension() == 3
             ? estimate_resources_3d(spec, elements, mesh_volume(mesh), altitudes, crossing)
             : estimate_resources(spec, elements, mesh_area(mesh), altitudes, crossing);
}

}  // namespace softshock
