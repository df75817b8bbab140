#include "integrator.hpp"

namespace softshock {

__attribute__((target_clones("avx512f", "avx2", "default"))) void predict_nodes(
    double dt, std::size_t begin, std::size_t end, double* __restrict x, double* __restrict y,
    double* __restrict vx, double* __restrict vy, const double* __restrict ax,
    const double* __restrict ay, PackedNode* __restrict nodes) {
  for (std::size_t i = begin; i < end; ++i) {
    x[i] += dt * vx[i] + 0.5 * dt * dt * ax[i];
    y[i] += dt * vy[i] + 0.5 * dt * dt * ay[i];
    nodes[i].lanes[0] = x[i], nodes[i].lanes[1] = y[i];
    vx[i] += 0.5 * dt * ax[i];
    vy[i] += 0.5 * dt * ay[i];
  }
}

__attribute__((target_clones("avx512f", "avx2", "default"))) void correct_nodes(
    double dt, std::size_t begin, std::size_t end, const NodeForce* __restrict force,
    const double* __restrict fext_x, const double* __restrict fext_y,
    const uint8_t* __restrict free_x, const uint8_t* __restrict free_y,
    const double* __restrict mass, double* __restrict ax, double* __restrict ay,
    double* __restrict vx, double* __restrict vy) {
  for (std::size_t i = begin; i < end; ++i) {
    ax[i] = free_x[i] * (force[i].lanes[0] + fext_x[i]) / mass[i];
    ay[i] = free_y[i] * (force[i].lanes[1] + fext_y[i]) / mass[i];
    vx[i] += 0.5 * dt * ax[i];
    vy[i] += 0.5 * dt * ay[i];
  }
}

}  // namespace softshock
