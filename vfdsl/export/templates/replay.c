/* replay: run the exported controller on recorded ticks, to check a build against Python.
 *
 *     ./replay [--params FILE] [--dt SECONDS] < ticks.txt
 *
 * One tick per line of standard input: q (@MACRO@_NUM_JOINTS numbers), then every input in declaration
 * order, whitespace-separated (nan and inf are read as such); a line may then carry every param in order
 * (@MACRO@_PARAM_LENGTH numbers more), as Controller.step(q, inputs, params) takes them: they are set
 * before the line's tick and kept for the next lines (a re-registered pivot in a recording). FILE holds
 * the params for the start (@MACRO@_PARAM_LENGTH numbers); without it they keep their defaults. dt
 * defaults to the scene's period. One line out per tick: the status, then dq with 17 significant digits (and for
 * a procedure " | " and the phase after the tick; for a teleoperated task " # ", the haptic force, the set-point,
 * the goal, the depth and following, as @API@_teleop gives them); for a refused tick "error CODE MESSAGE" (refused params: the check's meaning too; the tick is not run).
 * The controller is one for the whole run, as in a control loop.
 * Exit status: 0, or 2 for a usage or reading error: a line with another count of numbers or longer than
 * LINE_MAX_CHARS - 1 characters, a NUL byte, an unreadable FILE.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "@API@.h"

#define LINE_MAX_CHARS 65536
#define NQ @MACRO@_NUM_JOINTS
#define NU @MACRO@_INPUT_LENGTH
#define NP @MACRO@_PARAM_LENGTH
#define READ_END (-1)         /* read_text: nothing left */
#define READ_TOO_LONG (-2)    /* read_text: more than capacity - 1 characters */
#define READ_NUL (-3)         /* read_text: a NUL byte */
#define READ_FAILED (-4)      /* read_text: an error of the stream */

/* One line of `in` (one_line) or the whole rest of it into text, NUL-terminated, without the newline: its
 * length, or READ_END, READ_TOO_LONG, READ_NUL, READ_FAILED. */
static long read_text(FILE* in, char* text, long capacity, int one_line) {
  long n = 0;
  int ch;
  while ((ch = getc(in)) != EOF && !(one_line && ch == '\n')) {
    if (ch == 0) return READ_NUL;
    if (n + 1 >= capacity) return READ_TOO_LONG;
    text[n++] = (char) ch;
  }
  if (ferror(in)) return READ_FAILED;
  text[n] = 0;
  return ch == EOF && n == 0 && one_line ? READ_END : n;
}

/* The count of numbers in text (at most capacity are stored), or -1 when text holds anything else. */
static int read_numbers(const char* text, double* out, int capacity) {
  int n = 0;
  char* end;
  for (;;) {
    double v = strtod(text, &end);
    if (end == text) break;
    if (n < capacity) out[n] = v;
    ++n;
    text = end;
  }
  while (*text == ' ' || *text == '\t' || *text == '\r' || *text == '\n') ++text;
  return *text ? -1 : n;
}

static const char* read_error(long code) {
  return code == READ_NUL ? "holds a NUL byte" : code == READ_FAILED ? "could not be read"
                                                                      : "is longer than the limit";
}

/* Sets every param from values: 0, or prints "PLACE: error CODE MESSAGE[: what the check asks]" to out. */
static int set_params(@API@* ctrl, const double* values, FILE* out, const char* place) {
  int code = @API@_set_params(ctrl, values), check;
  if (code >= 0) return 0;
  check = @API@_error_check(ctrl);
  fprintf(out, "%serror %d %s%s%s\n", place, code, @API@_error_message(code), check >= 0 ? ": " : "",
          check >= 0 ? @API@_check_meaning(check) : "");
  return code;
}

static int load_params(@API@* ctrl, const char* path) {
  static char text[LINE_MAX_CHARS * 16];
  char place[1024];
  double values[NP + 1];
  long length;
  int n;
  FILE* f = fopen(path, "r");
  if (!f) { perror(path); return 2; }
  length = read_text(f, text, sizeof text, 0);
  fclose(f);
  if (length < 0) {
    fprintf(stderr, "%s %s (at most %ld characters)\n", path, read_error(length), (long) sizeof text - 1);
    return 2;
  }
  n = read_numbers(text, values, NP);
  if (n != NP) {
    fprintf(stderr, "%s: %d numbers, expected %d (every param in order)\n", path, n, NP);
    return 2;
  }
  snprintf(place, sizeof place, "%s: ", path);
  return set_params(ctrl, values, stderr, place) ? 2 : 0;
}

int main(int argc, char** argv) {
  static char line[LINE_MAX_CHARS];
  double values[NQ + NU + NP + 1], dq[NQ + 1];
  double dt = @API@_default_period();
  const char* params = 0;
  char* end;
  long number = 0, length;
  int i, status = 0;
  @API@* ctrl;
  for (i=1; i<argc; ++i) {
    if (!strcmp(argv[i], "--params") && i + 1 < argc) {
      params = argv[++i];
    } else if (!strcmp(argv[i], "--dt") && i + 1 < argc) {
      dt = strtod(argv[++i], &end);
      if (end == argv[i] || *end) { fprintf(stderr, "--dt %s: not a number of seconds\n", argv[i]); return 2; }
    } else {
      fprintf(stderr, "usage: %s [--params FILE] [--dt SECONDS] < ticks\n", argv[0]);
      return 2;
    }
  }
  ctrl = @API@_new();
  if (!ctrl) { fprintf(stderr, "@API@_new failed (out of memory)\n"); return 2; }
  if (params && load_params(ctrl, params)) { @API@_free(ctrl); return 2; }
  while ((length = read_text(stdin, line, sizeof line, 1)) != READ_END) {
    int n, code;
    ++number;
    if (length < 0) {
      fprintf(stderr, "line %ld %s (at most %d characters a line)\n", number, read_error(length),
              LINE_MAX_CHARS - 1);
      status = 2;
      break;
    }
    n = read_numbers(line, values, NQ + NU + NP);
    if (n == 0) continue;
    if (n != NQ + NU && (NP == 0 || n != NQ + NU + NP)) {
      if (NP) fprintf(stderr, "line %ld: %d numbers, expected %d (q, then every input) or %d (q, every input, then "
                              "every param)\n", number, n, NQ + NU, NQ + NU + NP);
      else fprintf(stderr, "line %ld: %d numbers, expected %d (q, then every input)\n", number, n, NQ + NU);
      status = 2;
      break;
    }
    if (n > NQ + NU && set_params(ctrl, values + NQ + NU, stdout, "")) continue;
    code = @API@_step(ctrl, values, values + NQ, dt, dq);
    if (code < 0) {
      printf("error %d %s\n", code, @API@_error_message(code));
      continue;
    }
    printf("%d", code);
    for (i=0; i<NQ; ++i) printf(" %.17g", dq[i]);
    if (@API@_num_phases() > 0) printf(" | %s", @API@_phase_name(@API@_phase(ctrl)));
    if (@API@_is_teleoperated()) {
      @API@_teleop_readout t;
      @API@_teleop(ctrl, &t);
      printf(" #");
      for (i=0; i<3; ++i) printf(" %.17g", t.force[i]);
      for (i=0; i<6; ++i) printf(" %.17g", t.setpoint[i]);
      for (i=0; i<3; ++i) printf(" %.17g", t.goal[i]);
      for (i=0; i<3; ++i) printf(" %.17g", t.depth[i]);
      printf(" %d", t.following);
    }
    printf("\n");
  }
  @API@_free(ctrl);
  return status;
}
