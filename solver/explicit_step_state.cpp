// ExplicitStep's state as named arrays, for checkpoints (run_state.hpp). Everything a step reads
// that an earlier step wrote is listed, and also what the diagnostics and the final sample read of
// the last evaluation (the element rows, the nodal-pressure arrays): a continued run then samples
// and steps exactly as the run that never stopped. A state array added to the step must be added
// here, or a continued run differs -- test_checkpoint's bitwise comparisons catch that.
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "explicit_step.hpp"

namespace softshock {

namespace {

template <class Visit>
void visit_element_state(ElementState& s, Visit& visit) {
  visit("element.f_xx", s.f_xx.data(), s.f_xx.size());
  visit("element.f_xy", s.f_xy.data(), s.f_xy.size());
  visit("element.f_yx", s.f_yx.data(), s.f_yx.size());
  visit("element.f_yy", s.f_yy.data(), s.f_yy.size());
  visit("element.pv_xx", s.pv_xx.data(), s.pv_xx.size());
  visit("element.pv_xy", s.pv_xy.data(), s.pv_xy.size());
  visit("element.pv_yx", s.pv_yx.data(), s.pv_yx.size());
  visit("element.pv_yy", s.pv_yy.data(), s.pv_yy.size());
  visit("element.viscosity", s.viscosity.data(), s.viscosity.size());
  visit("element.bulk_viscosity", s.bulk_viscosity.data(), s.bulk_viscosity.size());
}

template <class Visit>
void visit_element_state(Tet4State& s, Visit& visit) {
  visit("element.f", s.f.data(), s.f.size());
  visit("element.pv", s.pv.data(), s.pv.size());
}

const StateArray* find_array(const std::vector<StateArray>& arrays, const char* name) {
  for (const auto& a : arrays)
    if (a.name == name) return &a;
  return nullptr;
}

}  // namespace

template <class Element>
template <class Visit>
void ExplicitStep<Element>::visit_state(Visit&& visit) {
  static const char* const kComponent[] = {"0", "1", "2"};
  for (int c = 0; c < kDim; ++c) {
    const std::string k = kComponent[c];
    for (auto [name, v] :
         {std::pair{"node.x_", &nodes_.x[c]}, std::pair{"node.v_", &nodes_.v[c]},
          std::pair{"node.a_", &nodes_.a[c]}, std::pair{"node.fext_", &nodes_.fext[c]},
          std::pair{"node.p_", &nodes_.p[c]}, std::pair{"node.fprev_", &nodes_.fprev[c]}})
      visit((name + k).c_str(), v->data(), v->size());
  }
  // The rows: positions and nodal state of the last evaluation, all lanes doubles.
  static_assert(sizeof(Row) % sizeof(double) == 0);
  visit("node.rows", reinterpret_cast<double*>(rows_.data()),
        rows_.size() * (sizeof(Row) / sizeof(double)));
  for (auto [name, v] :
       {std::pair{"node.nodal_measure", &nodal_measure_}, std::pair{"node.nodal_j", &nodal_j_},
        std::pair{"node.nodal_sm", &nodal_sm_}, std::pair{"node.nodal_k", &nodal_k_},
        std::pair{"node.nodal_q", &nodal_q_}, std::pair{"element.j", &j_element_},
        std::pair{"element.s", &s_element_}})
    visit(name, v->data(), v->size());
  visit_element_state(state_, visit);
  if (damage_) damage_->visit_state(visit);  // d, H, degradations and the staggering's counters
}

template <class Element>
void ExplicitStep<Element>::save_state(std::vector<StateArray>& out) const {
  auto save = [&out](const char* name, const auto* data, std::size_t count) {
    StateArray a;
    a.name = name;
    if constexpr (std::is_same_v<std::remove_cv_t<std::remove_pointer_t<decltype(data)>>, float>) {
      a.single = true;
      a.f32.assign(data, data + count);
    } else {
      a.f64.assign(data, data + count);
    }
    out.push_back(std::move(a));
  };
  // visit_state hands out mutable pointers; saving only reads through them.
  const_cast<ExplicitStep*>(this)->visit_state(save);
}

template <class Element>
void ExplicitStep<Element>::restore_state(const std::vector<StateArray>& in) {
  auto restore = [&in](const char* name, auto* data, std::size_t count) {
    const StateArray* a = find_array(in, name);
    if (!a) throw std::invalid_argument(std::string("checkpoint: no state array ") + name);
    constexpr bool single = std::is_same_v<std::remove_pointer_t<decltype(data)>, float>;
    const std::size_t have = single ? a->f32.size() : a->f64.size();
    if (a->single != single || have != count) {
      throw std::invalid_argument(std::string("checkpoint: state array ") + name + " has " +
                                  std::to_string(have) + (a->single ? " floats" : " doubles") +
                                  ", the problem needs " + std::to_string(count));
    }
    if (count > 0)
      std::memcpy(data, single ? static_cast<const void*>(a->f32.data()) : a->f64.data(),
                  count * sizeof(*data));
  };
  visit_state(restore);
}

template void ExplicitStep<Tri3>::save_state(std::vector<StateArray>&) const;
template void ExplicitStep<Tri3>::restore_state(const std::vector<StateArray>&);
template void ExplicitStep<Tet4>::save_state(std::vector<StateArray>&) const;
template void ExplicitStep<Tet4>::restore_state(const std::vector<StateArray>&);

}  // namespace softshock
