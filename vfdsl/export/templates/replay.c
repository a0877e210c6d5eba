/* replay: run the exported controller on recorded ticks, to check a build against Python.
 *
 *     ./replay [--params FILE] [--dt SECONDS] < ticks.txt
 *
 * One tick per line of standard input: q (@API@_num_joints() numbers), then every input in declaration
 * order, whitespace-separated (nan and inf are read as such). FILE holds every param in order
 * (@API@_param_length() numbers); without it the params keep their defaults. dt defaults to the
 * scene's period. One line out per tick: the status, then dq with 17 significant digits; for a refused
 * tick "error CODE MESSAGE". The controller is one for the whole run, as in a control loop.
 * Exit status: 0, or 2 for a usage or reading error (a line with the wrong count of numbers).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "@API@.h"

#define LINE_MAX_CHARS 65536

static int read_numbers(char* text, double* out, int capacity) {
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

static int load_params(@API@* ctrl, const char* path) {
  static char text[LINE_MAX_CHARS * 16];
  double values[@NP@ + 1];
  size_t length;
  int n, code;
  FILE* f = fopen(path, "r");
  if (!f) { perror(path); return 2; }
  length = fread(text, 1, sizeof text - 1, f);
  fclose(f);
  text[length] = 0;
  n = read_numbers(text, values, @NP@);
  if (n != @NP@) {
    fprintf(stderr, "%s: %d numbers, expected %d (every param in order)\n", path, n, @NP@);
    return 2;
  }
  code = @API@_set_params(ctrl, values);
  if (code < 0) {
    int check = @API@_error_check(ctrl);
    fprintf(stderr, "%s: error %d %s%s%s\n", path, code, @API@_error_message(code), check >= 0 ? ": " : "",
            check >= 0 ? @API@_check_meaning(check) : "");
    return 2;
  }
  return 0;
}

int main(int argc, char** argv) {
  static char line[LINE_MAX_CHARS];
  double values[@NQ@ + @NU@ + 1], dq[@NQ@ + 1];
  double dt = @API@_default_period();
  const char* params = 0;
  long number = 0;
  int i, status = 0;
  @API@* ctrl;
  for (i=1; i<argc; ++i) {
    if (!strcmp(argv[i], "--params") && i + 1 < argc) params = argv[++i];
    else if (!strcmp(argv[i], "--dt") && i + 1 < argc) dt = strtod(argv[++i], 0);
    else {
      fprintf(stderr, "usage: %s [--params FILE] [--dt SECONDS] < ticks\n", argv[0]);
      return 2;
    }
  }
  ctrl = @API@_new();
  if (!ctrl) { fprintf(stderr, "@API@_new failed (out of memory)\n"); return 2; }
  if (params && load_params(ctrl, params)) { @API@_free(ctrl); return 2; }
  while (fgets(line, sizeof line, stdin)) {
    int n = read_numbers(line, values, @NQ@ + @NU@), code;
    ++number;
    if (n == 0) continue;
    if (n != @NQ@ + @NU@) {
      fprintf(stderr, "line %ld: %d numbers, expected %d (q, then every input)\n", number, n, @NQ@ + @NU@);
      status = 2;
      break;
    }
    code = @API@_step(ctrl, values, values + @NQ@, dt, dq);
    if (code < 0) {
      printf("error %d %s\n", code, @API@_error_message(code));
      continue;
    }
    printf("%d", code);
    for (i=0; i<@NQ@; ++i) printf(" %.17g", dq[i]);
    printf("\n");
  }
  @API@_free(ctrl);
  return status;
}
