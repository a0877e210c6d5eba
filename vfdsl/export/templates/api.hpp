/* @API@.hpp: a C++ owner of one @API@ controller (RAII; movable, not copyable), written by `vfdsl export`.
 *
 *     vfdsl::@CLASS@ ctrl;                        // throws std::runtime_error when @API@_new fails
 *     std::array<double, vfdsl::@CLASS@::num_joints> q, dq;
 *     int s = ctrl.step(q, inputs, dt, dq);          // the C API's codes; noexcept, no allocation
 *
 * The arrays q, inputs, dq and the params' values are vfdsl::numbers<N>: a pointer, or a C array or
 * std::array of at least N numbers (a smaller one does not compile).
 */
#ifndef @GUARD@_HPP
#define @GUARD@_HPP

#include <array>
#include <cstddef>
#include <stdexcept>
#include <type_traits>
#include "@API@.h"

namespace vfdsl {

#ifndef VFDSL_NUMBERS_HPP
#define VFDSL_NUMBERS_HPP
/* An argument of N numbers (T: const double, read; double, written): a pointer (nullptr included: the C API
 * refuses it), or a C array or std::array of at least N numbers; a smaller array is a compile-time error. */
template <class T, std::size_t N>
class numbers {
 public:
  template <class P, typename std::enable_if<std::is_pointer<P>::value && std::is_convertible<P, T*>::value,
                                             int>::type = 0>
  numbers(const P& pointer) noexcept : data_(pointer) {}
  numbers(std::nullptr_t) noexcept : data_(nullptr) {}
  template <class V, std::size_t M, typename std::enable_if<std::is_convertible<V*, T*>::value, int>::type = 0>
  numbers(V (&array)[M]) noexcept : data_(array) {
    static_assert(M >= N, "this array holds fewer numbers than the fixture reads or writes");
  }
  template <class V, std::size_t M, typename std::enable_if<std::is_convertible<V*, T*>::value, int>::type = 0>
  numbers(std::array<V, M>& array) noexcept : data_(array.data()) {
    static_assert(M >= N, "this array holds fewer numbers than the fixture reads or writes");
  }
  template <class V, std::size_t M, typename std::enable_if<std::is_convertible<const V*, T*>::value, int>::type = 0>
  numbers(const std::array<V, M>& array) noexcept : data_(array.data()) {
    static_assert(M >= N, "this array holds fewer numbers than the fixture reads or writes");
  }
  T* get() const noexcept { return data_; }

 private:
  T* data_;
};
#endif

class @CLASS@ {
 public:
  static constexpr int num_joints = @MACRO@_NUM_JOINTS;
  static constexpr int input_length = @MACRO@_INPUT_LENGTH;
  static constexpr int param_length = @MACRO@_PARAM_LENGTH;
  using joints_in = numbers<const double, @MACRO@_NUM_JOINTS>;
  using joints_out = numbers<double, @MACRO@_NUM_JOINTS>;
  using inputs_in = numbers<const double, @MACRO@_INPUT_LENGTH>;
  using params_in = numbers<const double, @MACRO@_PARAM_LENGTH>;

  @CLASS@() : ctrl_(@API@_new()) {
    if (!ctrl_) throw std::runtime_error("@API@_new failed: out of memory, or too many controllers");
  }
  ~@CLASS@() { @API@_free(ctrl_); }
  @CLASS@(const @CLASS@&) = delete;
  @CLASS@& operator=(const @CLASS@&) = delete;
  @CLASS@(@CLASS@&& other) noexcept : ctrl_(other.ctrl_) { other.ctrl_ = nullptr; }
  @CLASS@& operator=(@CLASS@&& other) noexcept {
    if (this != &other) {
      @API@_free(ctrl_);
      ctrl_ = other.ctrl_;
      other.ctrl_ = nullptr;
    }
    return *this;
  }

  /* Status bits (>= 0) or a VF_ERR_* code (< 0, dq zeros): see @API@.h. */
  int step(joints_in q, inputs_in inputs, double dt, joints_out dq) noexcept {
    return @API@_step(ctrl_, q.get(), inputs.get(), dt, dq.get());
  }
  int set_param(int index, const double* values) noexcept { return @API@_set_param(ctrl_, index, values); }
  int set_params(params_in values) noexcept { return @API@_set_params(ctrl_, values.get()); }
  int violations(@API@_violation* out, int capacity) const noexcept {
    return @API@_violations(ctrl_, out, capacity);
  }
  static const char* error_message(int code) noexcept { return @API@_error_message(code); }
  @API@* get() noexcept { return ctrl_; }

 private:
  @API@* ctrl_;
};

}  // namespace vfdsl

#endif
