/* @API@.hpp: a C++ owner of one @API@ controller (RAII; movable, not copyable), written by `vfdsl export`.
 *
 *     vfdsl::@TASK_ID@ ctrl;                        // throws std::runtime_error when @API@_new fails
 *     int s = ctrl.step(q, inputs, dt, dq);          // the C API's codes; noexcept, no allocation
 */
#ifndef @GUARD@_HPP
#define @GUARD@_HPP

#include <stdexcept>
#include "@API@.h"

namespace vfdsl {

class @TASK_ID@ {
 public:
  static constexpr int num_joints = @NQ@;
  static constexpr int input_length = @NU@;
  static constexpr int param_length = @NP@;

  @TASK_ID@() : ctrl_(@API@_new()) {
    if (!ctrl_) throw std::runtime_error("@API@_new failed: out of memory, or too many controllers");
  }
  ~@TASK_ID@() { @API@_free(ctrl_); }
  @TASK_ID@(const @TASK_ID@&) = delete;
  @TASK_ID@& operator=(const @TASK_ID@&) = delete;
  @TASK_ID@(@TASK_ID@&& other) noexcept : ctrl_(other.ctrl_) { other.ctrl_ = nullptr; }
  @TASK_ID@& operator=(@TASK_ID@&& other) noexcept {
    if (this != &other) {
      @API@_free(ctrl_);
      ctrl_ = other.ctrl_;
      other.ctrl_ = nullptr;
    }
    return *this;
  }

  /* Status bits (>= 0) or a VF_ERR_* code (< 0, dq zeros): see @API@.h. */
  int step(const double* q, const double* inputs, double dt, double* dq) noexcept {
    return @API@_step(ctrl_, q, inputs, dt, dq);
  }
  int set_param(int index, const double* values) noexcept { return @API@_set_param(ctrl_, index, values); }
  int set_params(const double* values) noexcept { return @API@_set_params(ctrl_, values); }
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
