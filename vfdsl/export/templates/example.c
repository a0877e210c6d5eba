/* example: what @API@ offers, and ten ticks of a control loop from the task's start configuration.
 *
 *     make && ./example
 */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "@API@.h"

int main(void) {
  double q[@NQ@ + 1], inputs[@NU@ + 1] = {0}, dq[@NQ@ + 1];
  double dt = @API@_default_period() > 0 ? @API@_default_period() : 0.001;
  @API@_violation violated[8];
  int i, k, n, tick;
  @API@* ctrl = @API@_new();
  if (!ctrl) { fprintf(stderr, "@API@_new failed\n"); return 1; }
  printf("@TASK@: %d joints, %d inputs, %d run-time params, %d constraint rows\n", @API@_num_joints(),
         @API@_num_inputs(), @API@_num_params(), @API@_num_rows());
  for (i=0; i<@API@_num_joints(); ++i) printf("  joint %-10s %s\n", @API@_joint_name(i), @API@_joint_unit(i));
  for (k=0; k<@API@_num_inputs(); ++k)
    printf("  input %-10s %d numbers, %s\n", @API@_input_name(k), @API@_input_size(k), @API@_input_unit(k));
  for (k=0; k<@API@_num_params(); ++k)
    printf("  param %-10s %s, %d numbers, %s\n", @API@_param_name(k), @API@_param_type(k), @API@_param_size(k),
           @API@_param_unit(k));

  memcpy(q, @API@_start(), sizeof(double) * @NQ@);
  for (i=0; i<@NU@; ++i) inputs[i] = 0.01 * (i + 1);     /* a small, constant push on every input */
  for (tick=0; tick<10; ++tick) {
    int status = @API@_step(ctrl, q, inputs, dt, dq);
    if (status < 0) { printf("refused: %s\n", @API@_error_message(status)); break; }
    for (i=0; i<@NQ@; ++i) q[i] += dq[i];            /* a perfect robot: it moves by dq */
    printf("tick %d: status %d, dq[0] = %.3g\n", tick, status, dq[0]);
    n = @API@_violations(ctrl, violated, 8);
    for (k=0; k<n && k<8; ++k)
      printf("  violated by %.3g %s: %s\n", violated[k].amount, violated[k].unit, violated[k].label);
  }
  q[0] = NAN;                                            /* NaN: refused before anything moves */
  printf("a NaN joint: %s\n", @API@_error_message(@API@_step(ctrl, q, inputs, dt, dq)));
  @API@_free(ctrl);
  return 0;
}
