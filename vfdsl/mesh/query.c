/* vfdsl mesh proximity query, one copy per mesh (the generator puts the mesh's tables above this text and
 * replaces @NAME@ by the mesh's symbol). A CasADi external function (see CasADi's docs, "external"):
 *
 *   @NAME@(arg, res, iw, w, mem)
 *     arg[0] a[3]      segment start (the task frame), in the mesh's frame, m
 *     arg[1] b[3]      segment end (the shaft frame; = a for a point), in the mesh's frame, m
 *     arg[2] [cutoff, side]   features farther than cutoff from the segment are ignored; side = +1: the free
 *                      side is where the normals point (keep out), -1: opposite (keep in)
 *     res[0] d[K]      signed distance of each feature: > 0 on the free side, < 0 through the surface
 *     res[1] s[K]      parameter of the segment's closest point x = a + s (b - a), in [0, 1]
 *     res[2] u[3K]     unit direction (column per feature) from the feature toward the free side at x
 *   Unused entries (fewer than K features within the cutoff): d = +inf, s = 0, u = 0. A violated fixture is
 *   never without a row: an end on the forbidden side always has one (see "far ends" below).
 *
 * The answer (vfdsl.mesh.brute.features computes the same by brute force over every triangle):
 * - hits: each triangle gives up to three, one per part of the segment: its closest point to the segment's start
 *   a (part 0), to its end b (part 2), and the closest pair of the segment and the triangle when the segment's
 *   point of that pair lies strictly between a and b (part 1). A hit is its distance, its parameter s, its point
 *   c on the triangle and its direction u = (x - c) / |x - c| from c to the segment's point x (touching, at a
 *   distance <= 1e-12: the triangle's normal times side). A point (a = b) has part 0 only. Hits farther than
 *   the cutoff are dropped.
 * - order: by distance, then part, then the coordinates of c, then s (a total order up to repeats of a hit).
 * - merging: per part, in that order, a hit is kept unless its u is within VFM_SIMILAR (cosine) of a hit kept
 *   before it in its part (a feature seen through several triangles, a patch of one wall: one row).
 * - far ends: an end (a point's only part) with no hit within the cutoff whose nearest feature on the mesh, at
 *   whatever distance, puts it on the forbidden side keeps that feature as its one hit (a tool 14 mm outside a
 *   keep-in channel, or deep inside a keep-out volume: the row asks back by the whole distance). An end far on the
 *   free side has no hit: its rows would be 0 >= -inf. Between the ends no such rule is needed: a segment whose
 *   ends are both on the free side and whose middle is not crosses the surface (a hit at distance 0).
 * - rows: the first kept hit of each part, then the nearest of the other kept hits, K in all, in that order.
 * - side: the side of a part's point comes from the angle-weighted pseudo-normal (Baerentzen & Aanaes 2005) of
 *   its nearest feature (face, edge or vertex) on the mesh, which is right at faces, edges and vertices of a
 *   closed, consistently oriented mesh: for an end, its first hit's; between the ends, the first hit's point x
 *   is checked against every triangle within that hit's distance. The part's other hits take that side.
 *   (A nearest feature that two triangles give at the same distance, an edge they share, is the one whose point
 *   comes first in the order of coordinates: the answer is the same bits whatever the BVH.)
 *
 * How: a best-first walk of a BVH of oriented boxes (vfdsl/mesh/tables.py), one priority queue (a binary heap)
 * of boxes, pending entries and hits keyed by distance, a box by a lower bound of its hits' distances over the
 * parts it may still give a kept hit to (the point-box distance, a lower bound of the segment-box distance, in the
 * box's frame, lowered for rounding): hits come out in the order above, so each is merged or kept as it comes out; a
 * box is expanded as soon as it is ahead of the queue (the order in which boxes are expanded does not change the
 * answer, only how soon the walk stops). A part is done when it has K kept hits, or one and K rows in all: its kept
 * hits, the other parts' and the rows of the ends with no kept hit yet that will have one (its later hits could not
 * be rows: they come after K - P others, P the parts with a row); the walk stops when every part is done. Whether an
 * end will have a row is looked up, once a call, only when it decides: its nearest feature (the far ends' search,
 * below) is within the cutoff, or puts it on the forbidden side. (At benchmarks/mesh.py's slowest states the tip's and
 * the shaft's first hits come at 1.9-2.5 mm, after the hits between the ends that complete the rows; the walk went on
 * between the ends until then.) Queued items whose parts are all done are then dropped at once. A box is skipped for
 * a part when it is beyond the cutoff; a hit is dropped as soon as it is within VFM_SIMILAR of a kept hit of its part
 * (it would be merged).
 * - pending entries: a triangle's hit between the ends (its closest pair with the segment: three segment-edge
 *   pairs and a face test, the costliest part of a triangle) is not computed when its leaf is expanded. If it
 *   exists, its segment point is interior, so it is a local, hence the global, least of the distance from the
 *   segment's line (convex along the line): the triangle's projection on the plane normal to ab gives, in two
 *   dimensions, its distance (the line's, never more than the hit's) and its direction u (the projection's
 *   closest point's, up to rounding; a leaf's distinct vertices, listed by the tables, are projected once, and u is
 *   compared with the kept hits' directions in that plane; a projection of no area, a triangle with an edge
 *   parallel to ab, as the straight wall's beside the example's upright shaft at its start, is measured on its
 *   edges). The triangle waits in the queue as a pending entry keyed by that distance (a box's key, lowered by
 *   VFM_LINE_SLACK), and when it comes out the hit is computed only if that part is not done and u is not within
 *   VFM_SIMILAR + VFM_SAME_SLACK of a kept hit (kept hits come out before it: its hit would be merged), u being
 *   trusted only from VFM_SAME_FROM away. Along a wall nearly every triangle's hit is merged: at benchmarks/mesh.py's
 *   slowest states 14 pairs are computed where 508 were. A leaf's pending entries wait as one run (its slots linked
 *   in order), queued as its first entry: when that comes out, the rest of the run goes back into the queue, less
 *   the entries merged for sure by then, before the first's hit is placed (so the queue always holds the least key of
 *   every entry not yet out, as if each were queued alone). Along a wall the first entry's kept hit merges the rest:
 *   at the bend of benchmarks/mesh.py 144 entries a call went in and out of the queue, and 32 runs do now.
 * (Boxes are not tested against the kept hits' cones: along a wall, where the walk works longest, a box's hits
 * spread over more than one cone, and the test skipped 322 boxes in 1.9 million on benchmarks/mesh.py's states; nor
 * against their union, in angle about the segment: a leaf there spans 60-90 deg seen from the shaft, and the test
 * skipped 13 of the 164 boxes it was asked about at the slowest state, for 18 % more instructions.)
 * The walk's memory (vfm_walk, with a queue of VFM_HEAP entries) is the work vector w the caller gives (CasADi
 * sizes it by @NAME@_work and allocates it with the caller's work arrays: once per controller); every call
 * writes what it reads first, so no call depends on another. When the queue or its VFM_HEAP slots for hits and
 * pending entries are full, its farthest entry is dropped and the walk stops before that distance (the horizon);
 * the rest of the answer is then found one kept hit at a time, each the first hit after the last taken, by
 * depth-first walks with a fixed stack: the same answer. Nothing is allocated; iw and mem are unused.
 *
 * One file, over 500 lines, on purpose: it is the text of one translation unit per mesh (vfdsl/mesh/external.py
 * puts the mesh's tables above it, names its symbols and keys the cache by this text), compiled alone or into the
 * task's library, and this comment states the answer that the whole walk implements; its parts (the closest-point
 * geometry, the queue, the walk, CasADi's interface) are static functions of that unit, inlined into the walk.
 */
#include <math.h>

#ifndef casadi_real
#define casadi_real double
#endif
#ifndef casadi_int
#define casadi_int long long int
#endif
#ifndef VFM_EXPORT
#define VFM_EXPORT __attribute__((visibility("default")))
#endif
#ifndef VFM_HEAP
#define VFM_HEAP 1024
#endif

#define VFM_STACK 128
#define VFM_TOUCH 1e-12
#define VFM_NN ((int)(sizeof(vfm_nodes) / (2 * sizeof(int))))   /* nodes of the BVH */
#define VFM_PENDING (-1)            /* region of a pending entry: a triangle's hit between the ends, not computed */
#define VFM_LINE_SLACK 1e-9         /* relative: keys (a box's bound, a pending entry's distance) lowered by this, and
                                       a segment's (box and pending) by the walk's `slack` more, so that rounding
                                       keeps them lower bounds */
#define VFM_SAME_SLACK 1e-9         /* cosine: a pending entry's hit is merged for sure beyond VFM_SIMILAR + this ... */
#define VFM_SAME_FROM 1e-5          /* m: ... when the triangle is at least this far from the segment's line (its
                                       direction's rounding is then below 1e-11) */

typedef struct {
  double dist;      /* unsigned distance */
  double s;         /* the segment's point x = a + s (b - a) */
  double c[3];      /* the point on the triangle */
  double u[3];      /* unit from c to x (touching: the face's normal times side) */
  int t, region;    /* triangle and feature: 0 face, 1 + e edge e, 4 + i vertex i (vfm_point_triangle) */
  int part;         /* 0 the segment's start, 2 its end, 1 between */
  int next;         /* a queued pending entry: the slot of the next entry of its run, or -1 */
} vfm_hit;          /* also a pending entry (region VFM_PENDING: dist its key; when s = 1, u[0], u[1] its hit's
                       direction in the walk's e1, e2) */

typedef struct {
  double key;       /* a box: a lower bound of its hits' distances; a hit: its distance */
  int ref;          /* a node (< VFM_NN), a run of pending entries from slot ref - VFM_NN, or (< 0) the hit in slot
                       -1 - ref */
  int mask;         /* a box: the parts (bit p) it may give a kept hit to */
} vfm_item;

typedef struct {
  double d2, c[3];  /* squared distance, the point on the mesh */
  int t, region;    /* triangle (-1: none found), feature */
} vfm_near;         /* a point's nearest feature on the mesh */

typedef struct {
  const double *a, *b;
  double ab[3], unit[3], len, e1[3], e2[3], cutoff, side;  /* unit = ab / len; e1, e2: an orthonormal basis of the
                                                              plane normal to ab */
  double slack;                     /* m: the rounding of a distance bound from differences of coordinates, 1e-15
                                       (1 + 4 max |a_i|, |b_i|): a few units in their last place (the distance of a
                                       box the segment crosses came out up to 2e-18 m, and its hits at distance 0
                                       after another triangle's: an answer unlike the brute force's) */
  int point, parts;                 /* parts: 1 for a point, 7 for a segment */
  vfm_item heap[VFM_HEAP];
  vfm_hit slot[VFM_HEAP];
  int size, used, nfree, free_slot[VFM_HEAP];
  int taken;                        /* the top item is out (in hand) but still in the heap: the next push takes its
                                       place and goes down (one sift where a removal and a push were two) */
  double horizon;                   /* entries at or beyond it may have been dropped */
  int successor;                    /* the depth-first mode: hits after `after`, the first in `best` */
  vfm_hit leaf[3 * VFM_LEAF];       /* the best-first mode: a leaf's hits, before they are taken or queued */
  int nleaf;
  vfm_hit after, best;
  int found;
  vfm_hit kept[3][VFM_K];
  double plane[VFM_K][2];           /* the kept hits between the ends: u's coordinates in e1, e2 */
  int count[3], total, done;         /* done: the parts (bit p) done, from count and total (vfm_counted) */
  double part_side[3];
  int known;                        /* ends (bit p) whose nearest feature is in near[p / 2] (vfm_end_near) */
  vfm_near near[2];
} vfm_walk;

static double vfm_dot(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static double vfm_dotf(const double* a, const float* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static double vfm_clamp01(double x) { return x < 0 ? 0 : (x > 1 ? 1 : x); }

static int vfm_is_leaf(int node) { return vfm_nodes[2 * node] < 0; }

/* a . b over the first n (2 or 3) coordinates, summed in order. */
static double vfm_dotn(int n, const double* a, const double* b) {
  double s = a[0] * b[0] + a[1] * b[1];
  return n == 3 ? s + a[2] * b[2] : s;
}

/* Closest point on triangle (a, b, c) to p in n (2 or 3) dimensions (Ericson, Real-Time Collision Detection,
 * 5.1.5); region: 0 face, 1 + e edge e (edges (0,1), (1,2), (2,0)), 4 + i vertex i. */
static void vfm_closest_point(int n, const double* p, const double* a, const double* b, const double* c,
                              double* out, int* region) {
  double ab[3] = {0}, ac[3] = {0}, ap[3] = {0}, bp[3] = {0}, cp[3] = {0};
  int i;
  for (i = 0; i < n; ++i) { ab[i] = b[i] - a[i]; ac[i] = c[i] - a[i]; ap[i] = p[i] - a[i]; }
  double d1 = vfm_dotn(n, ab, ap), d2 = vfm_dotn(n, ac, ap);
  if (d1 <= 0 && d2 <= 0) { for (i = 0; i < n; ++i) out[i] = a[i]; *region = 4; return; }
  for (i = 0; i < n; ++i) bp[i] = p[i] - b[i];
  double d3 = vfm_dotn(n, ab, bp), d4 = vfm_dotn(n, ac, bp);
  if (d3 >= 0 && d4 <= d3) { for (i = 0; i < n; ++i) out[i] = b[i]; *region = 5; return; }
  double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    double v = d1 / (d1 - d3);
    for (i = 0; i < n; ++i) out[i] = a[i] + v * ab[i];
    *region = 1; return;
  }
  for (i = 0; i < n; ++i) cp[i] = p[i] - c[i];
  double d5 = vfm_dotn(n, ab, cp), d6 = vfm_dotn(n, ac, cp);
  if (d6 >= 0 && d5 <= d6) { for (i = 0; i < n; ++i) out[i] = c[i]; *region = 6; return; }
  double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    double w = d2 / (d2 - d6);
    for (i = 0; i < n; ++i) out[i] = a[i] + w * ac[i];
    *region = 3; return;
  }
  double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    for (i = 0; i < n; ++i) out[i] = b[i] + w * (c[i] - b[i]);
    *region = 2; return;
  }
  double denom = 1.0 / (va + vb + vc), v = vb * denom, w = vc * denom;
  for (i = 0; i < n; ++i) out[i] = a[i] + ab[i] * v + ac[i] * w;
  *region = 0;
}

static void vfm_point_triangle(const double* p, const double* a, const double* b, const double* c,
                               double* out, int* region) {
  vfm_closest_point(3, p, a, b, c, out, region);
}

/* Closest points of segments p1 q1 and p2 q2 (Ericson 5.1.9): parameters s, t in [0, 1]. */
static void vfm_segment_segment(const double* p1, const double* q1, const double* p2, const double* q2,
                                double* s, double* t) {
  double d1[3], d2[3], r[3];
  int i;
  for (i = 0; i < 3; ++i) { d1[i] = q1[i] - p1[i]; d2[i] = q2[i] - p2[i]; r[i] = p1[i] - p2[i]; }
  double a = vfm_dot(d1, d1), e = vfm_dot(d2, d2), f = vfm_dot(d2, r);
  const double eps = 1e-30;
  if (a <= eps && e <= eps) { *s = 0; *t = 0; return; }
  if (a <= eps) { *s = 0; *t = vfm_clamp01(f / e); return; }
  double c = vfm_dot(d1, r);
  if (e <= eps) { *t = 0; *s = vfm_clamp01(-c / a); return; }
  double b = vfm_dot(d1, d2), denom = a * e - b * b;
  *s = denom > eps ? vfm_clamp01((b * f - c * e) / denom) : 0;
  *t = (b * *s + f) / e;
  if (*t < 0) { *t = 0; *s = vfm_clamp01(-c / a); }
  else if (*t > 1) { *t = 1; *s = vfm_clamp01((b - c) / a); }
}

static double vfm_dist2(const double* x, const double* y) {
  double d[3] = {x[0] - y[0], x[1] - y[1], x[2] - y[2]};
  return vfm_dot(d, d);
}

/* The (unnormalized) normal of triangle t, in double from its vertices. */
static void vfm_normal(int t, double* n) {
  const int* tri = vfm_triangles + 3 * t;
  const double *p = vfm_vertices + 3 * tri[0], *q = vfm_vertices + 3 * tri[1], *r = vfm_vertices + 3 * tri[2];
  double e1[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, e2[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]};
  n[0] = e1[1] * e2[2] - e1[2] * e2[1];
  n[1] = e1[2] * e2[0] - e1[0] * e2[2];
  n[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

/* The closest pair of segment a b and triangle t (v its corners), given each end's closest point ca, cb (squared
 * distances da2, db2, regions ra, rb): the segment's parameter, the triangle's point, its region and the squared
 * distance (0 when the segment crosses the face). */
static double vfm_pair(const vfm_walk* w, int t, const double* const* v, const double* ca, double da2, int ra,
                       const double* cb, double db2, int rb, double* s_out, double* c_out, int* r_out) {
  const double *a = w->a, *b = w->b;
  double best, c[3], x[3], n[3], da = 0, db = 0;
  int i, e, region, far = db2 < da2;
  best = far ? db2 : da2;
  *s_out = far; *r_out = far ? rb : ra;
  for (i = 0; i < 3; ++i) c_out[i] = far ? cb[i] : ca[i];
  vfm_normal(t, n);
  for (i = 0; i < 3; ++i) { da += (a[i] - v[0][i]) * n[i]; db += (b[i] - v[0][i]) * n[i]; }
  if (da * db < 0) {                  /* the segment through the face: distance 0 */
    double s = da / (da - db);
    for (i = 0; i < 3; ++i) x[i] = a[i] + s * w->ab[i];
    vfm_point_triangle(x, v[0], v[1], v[2], c, &region);
    if (region == 0) {
      *s_out = s; *r_out = 0;
      for (i = 0; i < 3; ++i) c_out[i] = x[i];
      return 0;
    }
  }
  for (e = 0; e < 3; ++e) {           /* the segment to an edge of the triangle */
    const double *p = v[e], *q = v[(e + 1) % 3];
    double s, t2;
    vfm_segment_segment(a, b, p, q, &s, &t2);
    double d2 = 0;
    for (i = 0; i < 3; ++i) {
      x[i] = a[i] + s * w->ab[i];
      c[i] = p[i] + t2 * (q[i] - p[i]);
      d2 += (x[i] - c[i]) * (x[i] - c[i]);
    }
    if (d2 < best) {
      best = d2; *s_out = s;
      *r_out = t2 <= 0 ? 4 + e : (t2 >= 1 ? 4 + (e + 1) % 3 : 1 + e);
      for (i = 0; i < 3; ++i) c_out[i] = c[i];
    }
  }
  return best;
}

/* -1, 0 or 1 as point x comes before, with or after y in the order of their coordinates. */
static int vfm_compare_points(const double* x, const double* y) {
  int i;
  for (i = 0; i < 3; ++i) if (x[i] != y[i]) return x[i] < y[i] ? -1 : 1;
  return 0;
}

/* Whether hit x comes before hit y (distance, part, c, s). */
static int vfm_before(const vfm_hit* x, const vfm_hit* y) {
  int order;
  if (x->dist != y->dist) return x->dist < y->dist;
  if (x->part != y->part) return x->part < y->part;
  order = vfm_compare_points(x->c, y->c);
  return order ? order < 0 : x->s < y->s;
}

static int vfm_done(const vfm_walk* w, int p) { return w->done >> p & 1; }

static void vfm_nearest(const double* x, double* best2, int* t_best, int* r_best, double* near);
static double vfm_side_of(const vfm_walk* w, const double* x, const double* c, int t, int region);

/* End p's (0: a, 2: b) nearest feature on the mesh, at whatever distance: looked up once a call. */
static const vfm_near* vfm_end_near(vfm_walk* w, int p) {
  vfm_near* e = &w->near[p / 2];
  if (!(w->known >> p & 1)) {
    e->d2 = INFINITY; e->t = -1; e->region = 0; e->c[0] = e->c[1] = e->c[2] = 0;
    vfm_nearest(p ? w->b : w->a, &e->d2, &e->t, &e->region, e->c);
    w->known |= 1 << p;
  }
  return e;
}

/* Whether end p, with no kept hit yet, will have a row of its own: a hit within the cutoff (its nearest feature), or
 * by the far ends' rule (its nearest feature puts it on the forbidden side). */
static int vfm_end_row(vfm_walk* w, int p) {
  const vfm_near* e = vfm_end_near(w, p);
  return e->t >= 0 && (e->d2 <= w->cutoff * w->cutoff || vfm_side_of(w, p ? w->b : w->a, e->c, e->t, e->region) < 0);
}

/* One more kept hit of part p (in w->kept[p][w->count[p]]): a part is done when it has K kept hits, or one and K rows
 * in all, the kept hits and the rows of the ends to come (vfm_end_row, asked only when it decides). */
static void vfm_counted(vfm_walk* w, int p) {
  int q, waiting = 0, coming = 0;
  ++w->count[p];
  ++w->total;
  for (q = 0; q < 3; q += 2) waiting += (w->parts >> q & 1) && w->count[q] == 0;
  if (w->total < VFM_K && w->total + waiting >= VFM_K)
    for (q = 0; q < 3; q += 2) if ((w->parts >> q & 1) && w->count[q] == 0) coming += vfm_end_row(w, q);
  w->done = 0;
  for (q = 0; q < 3; ++q)
    if (w->count[q] >= VFM_K || (w->count[q] > 0 && w->total + coming >= VFM_K)) w->done |= 1 << q;
}

/* Whether direction u is within VFM_SIMILAR (cosine) of a kept hit of part p (it would be merged). */
static int vfm_merged(const vfm_walk* w, int p, const double* u) {
  int k;
  for (k = 0; k < w->count[p]; ++k) if (vfm_dot(w->kept[p][k].u, u) > VFM_SIMILAR) return 1;
  return 0;
}

/* Whether a pending entry's hit, if it has one, would be merged: its direction (exact up to rounding) is within
 * VFM_SIMILAR of a kept hit between the ends by more than the rounding of either. */
static int vfm_merged_for_sure(const vfm_walk* w, const vfm_hit* pending) {
  int k;
  if (!(pending->s > 0)) return 0;
  for (k = 0; k < w->count[1]; ++k)
    if (pending->u[0] * w->plane[k][0] + pending->u[1] * w->plane[k][1] > VFM_SIMILAR + VFM_SAME_SLACK) return 1;
  return 0;
}

/* x in the frame of node's oriented box (centre, axes, half-sides: vfm_boxes[15 node ...]). */
static void vfm_local(int node, const double* x, double* y) {
  const double* box = vfm_boxes + 15 * node;
  double d[3] = {x[0] - box[0], x[1] - box[1], x[2] - box[2]};
  int i;
  for (i = 0; i < 3; ++i) y[i] = vfm_dot(box + 3 + 3 * i, d);
}

/* The distance from point y (in the box's frame) to the box of half-sides h. */
static double vfm_point_box(const double* y, const double* h) {
  double d2 = 0;
  int i;
  for (i = 0; i < 3; ++i) {
    double g = fabs(y[i]) - h[i];
    if (g > 0) d2 += g * g;
  }
  return sqrt(d2);
}

/* A lower bound of the distance from segment p p + z len (in the box's frame, z a unit vector) to the box of half-sides
 * h: a point x of the box lies sqrt(r^2 + e^2) from the segment, r its distance from the segment's line and e how far
 * its projection on the line falls beyond the segment. e is at least the gap between the box's projection on the line
 * and the segment; r at least n . c - sum_i h_i |n_i| for any unit n normal to the line (c the box's centre less p),
 * here the largest over the normals of the box's projected edges (z x e_i) and the centre's own direction, which is r's
 * least where that least is on an edge. Near-exact along a wall (1-5 % more boxes out of the queue than with the exact
 * distance at benchmarks/mesh.py's states) for fewer instructions (vfm_useful: 285 a box where it took 430, with no
 * search over the pieces of a piecewise quadratic nor a branch on each cut). */
static double vfm_segment_box(const double* p, const double* z, double len, const double* h) {
  double c[3], along = 0, spread = 0, r = 0, e = 0, cc = 0, hc = 0;
  int i;
  for (i = 0; i < 3; ++i) { along -= p[i] * z[i]; spread += h[i] * fabs(z[i]); }
  if (along - spread > len) e = along - spread - len;
  else if (along + spread < 0) e = -(along + spread);
  for (i = 0; i < 3; ++i) { c[i] = -p[i] - along * z[i]; cc += c[i] * c[i]; hc += h[i] * fabs(c[i]); }
  if (cc > hc) r = (cc - hc) / sqrt(cc);
  for (i = 0; i < 3; ++i) {               /* n along z x e_i: its components j, k are z_k, -z_j over their norm */
    int j = (i + 1) % 3, k = (i + 2) % 3;
    double m2 = z[j] * z[j] + z[k] * z[k], g = fabs(z[k] * c[j] - z[j] * c[k]) - h[j] * fabs(z[k]) - h[k] * fabs(z[j]);
    if (g > 0 && g * g > r * r * m2) r = g / sqrt(m2);
  }
  return sqrt(r * r + e * e);
}

/* The parts of `mask` to which box `node` may still give a kept hit (within the cutoff, not done), and in *key
 * the least lower bound of their hits' distances. */
static int vfm_useful(const vfm_walk* w, int node, int mask, double* key) {
  const double* h = vfm_boxes + 15 * node + 12;
  double la[3], lb[3], lz[3], bound, best = INFINITY;
  int i, p, out = 0;
  mask &= w->parts & ~w->done;
  if (mask & 3) vfm_local(node, w->a, la);
  if (mask & 4) vfm_local(node, w->b, lb);
  for (p = 0; p < 3; ++p) {
    if (!(mask >> p & 1)) continue;
    if (p == 1) {
      for (i = 0; i < 3; ++i) lz[i] = vfm_dot(vfm_boxes + 15 * node + 3 + 3 * i, w->unit);
      bound = vfm_segment_box(la, lz, w->len, h) - w->slack;
      if (isnan(bound)) bound = 0;
    } else {
      bound = vfm_point_box(p ? lb : la, h);
    }
    if (bound > w->cutoff) continue;
    out |= 1 << p;
    if (bound < best) best = bound;
  }
  *key = best * (1 - VFM_LINE_SLACK);  /* a lower bound, lowered for rounding */
  return out;
}

/* A queued box's parts when it comes out: those not done since. */
static int vfm_still(const vfm_walk* w, const vfm_item* item) { return item->mask & ~w->done; }

/* The queue: a binary heap of items, least first (key, then boxes and pending entries before hits, then the hits'
 * order). The item taken out of the top stays there until the next push takes its place (most items that come out
 * are followed by one: a box's farther child, the rest of a run) or the heap is read (vfm_settle). */
static int vfm_tie_before(const vfm_walk* w, const vfm_item* x, const vfm_item* y) {
  if ((x->ref >= 0) != (y->ref >= 0)) return x->ref >= 0;
  if (x->ref >= 0) return x->ref < y->ref;
  return vfm_before(&w->slot[-1 - x->ref], &w->slot[-1 - y->ref]);
}

static int vfm_item_before(const vfm_walk* w, const vfm_item* x, const vfm_item* y) {
  return x->key < y->key || (x->key == y->key && vfm_tie_before(w, x, y));
}

static void vfm_sift_up(vfm_walk* w, int i) {
  vfm_item item = w->heap[i];
  while (i > 0) {
    int parent = (i - 1) / 2;
    if (!vfm_item_before(w, &item, &w->heap[parent])) break;
    w->heap[i] = w->heap[parent];
    i = parent;
  }
  w->heap[i] = item;
}

/* Item into the hole at i, down to its place in i's subtree. */
static void vfm_sift_down(vfm_walk* w, int i, vfm_item item) {
  int child;
  while ((child = 2 * i + 1) < w->size) {
    if (child + 1 < w->size && vfm_item_before(w, &w->heap[child + 1], &w->heap[child])) ++child;
    if (!vfm_item_before(w, &w->heap[child], &item)) break;
    w->heap[i] = w->heap[child];
    i = child;
  }
  w->heap[i] = item;
}

/* Removes heap item i: the last item takes its place, and goes up or down to where it belongs. */
static void vfm_remove(vfm_walk* w, int i) {
  vfm_item last = w->heap[--w->size];
  if (i == w->size) return;
  if (i > 0 && vfm_item_before(w, &last, &w->heap[(i - 1) / 2])) { w->heap[i] = last; vfm_sift_up(w, i); }
  else vfm_sift_down(w, i, last);
}

/* The item taken out of the top is removed now, before the heap is read (unless a push took its place). */
static void vfm_settle(vfm_walk* w) {
  if (w->taken) { w->taken = 0; vfm_remove(w, 0); }
}

static void vfm_free(vfm_walk* w, int s) { w->free_slot[w->nfree++] = s; }

/* Frees the slots of a queued item: a hit's, a pending run's (each entry's). */
static void vfm_release(vfm_walk* w, int ref) {
  int s;
  if (ref < 0) vfm_free(w, -1 - ref);
  else if (ref >= VFM_NN)
    for (s = ref - VFM_NN; s >= 0; s = w->slot[s].next) vfm_free(w, s);
}

/* Room for an item of `key` that needs `slots` free slots: while the queue or its slots are full, the farthest entry
 * (this one, or one queued) is dropped and the horizon comes down to its key. Returns 0 when this item is dropped. */
static int vfm_room(vfm_walk* w, double key, int slots) {
  int i, far;
  if (key >= w->horizon) return 0;
  if (w->size - w->taken < VFM_HEAP && VFM_HEAP - w->used + w->nfree >= slots) return 1;
  vfm_settle(w);
  while (w->size == VFM_HEAP || VFM_HEAP - w->used + w->nfree < slots) {
    for (far = 0, i = 1; i < w->size; ++i) if (w->heap[i].key > w->heap[far].key) far = i;
    if (w->size == 0 || key >= w->heap[far].key) { w->horizon = key; return 0; }
    w->horizon = w->heap[far].key;
    vfm_release(w, w->heap[far].ref);
    vfm_remove(w, far);
  }
  return 1;
}

/* Drops the queued items that can give no kept hit any more (every part they serve is done), and makes the rest a
 * heap again (Floyd's: each parent's subtree from the last up). */
static void vfm_purge(vfm_walk* w) {
  int i, n = 0;
  vfm_settle(w);
  for (i = 0; i < w->size; ++i) {
    const vfm_item* item = &w->heap[i];
    int live = item->ref < 0 ? !vfm_done(w, w->slot[-1 - item->ref].part)
                             : (item->ref >= VFM_NN ? !vfm_done(w, 1) : (item->mask & ~w->done) != 0);
    if (live) w->heap[n++] = *item;
    else vfm_release(w, item->ref);
  }
  w->size = n;
  for (i = n / 2 - 1; i >= 0; --i) vfm_sift_down(w, i, w->heap[i]);
}

static void vfm_push(vfm_walk* w, vfm_item item) {
  if (w->taken) { w->taken = 0; vfm_sift_down(w, 0, item); return; }
  w->heap[w->size] = item;
  vfm_sift_up(w, w->size++);
}

/* The parts of leaf item `item` to expand now: those whose bound is within the item's key (part 1's always is: a
 * segment is no farther than its ends). An end whose bound is beyond it waits: the leaf is queued again for that end,
 * keyed by its bound (its hits come out no sooner), and is seldom expanded for it (the walk stops first). */
static int vfm_split(vfm_walk* w, const vfm_item* item) {
  const double* h = vfm_boxes + 15 * item->ref + 12;
  double y[3], bound, key = INFINITY;
  int p, later = 0;
  for (p = 0; p < 3; p += 2) {
    if (!(item->mask >> p & 1)) continue;
    vfm_local(item->ref, p ? w->b : w->a, y);
    bound = vfm_point_box(y, h) * (1 - VFM_LINE_SLACK);
    if (bound > item->key) { later |= 1 << p; if (bound < key) key = bound; }
  }
  if (later && vfm_room(w, key, 0)) { vfm_item rest = {key, item->ref, later}; vfm_push(w, rest); }
  return item->mask & ~later;
}

/* A hit found on a triangle: queued (best-first walk) or compared with the best so far (depth-first mode). */
static void vfm_offer(vfm_walk* w, const vfm_hit* hit) {
  if (hit->dist > w->cutoff || vfm_merged(w, hit->part, hit->u)) return;
  if (w->successor) {
    if (vfm_before(&w->after, hit) && (!w->found || vfm_before(hit, &w->best))) { w->best = *hit; w->found = 1; }
    return;
  }
  w->leaf[w->nleaf++] = *hit;
}

static int vfm_is_pending(const vfm_hit* e) { return e->region == VFM_PENDING; }

static int vfm_slot(vfm_walk* w) { return w->nfree > 0 ? w->free_slot[--w->nfree] : w->used++; }

/* A hit into the queue. */
static void vfm_queue(vfm_walk* w, const vfm_hit* hit) {
  if (!vfm_room(w, hit->dist, 1)) return;
  int s = vfm_slot(w);
  w->slot[s] = *hit;
  vfm_item item = {hit->dist, -1 - s, 0};
  vfm_push(w, item);
}

/* A run of pending entries (slots linked by `next`, in order) into the queue from slot s on, less those whose hits are
 * merged for sure by now (or all, part 1 done): one item, keyed by its first entry and queued as a box is (before
 * the hits of its key), that comes out as that entry; the rest of the run goes back in then. */
static void vfm_queue_run(vfm_walk* w, int s) {
  for (; s >= 0 && (vfm_done(w, 1) || vfm_merged_for_sure(w, &w->slot[s])); s = w->slot[s].next) vfm_free(w, s);
  if (s < 0) return;
  if (!vfm_room(w, w->slot[s].dist, 0)) { vfm_release(w, VFM_NN + s); return; }
  vfm_item item = {w->slot[s].dist, VFM_NN + s, 0};
  vfm_push(w, item);
}

static void vfm_make_hit(const vfm_walk* w, int t, int part, double s, const double* c, int region, double d2,
                         vfm_hit* hit) {
  int i;
  double x[3];
  hit->dist = sqrt(d2); hit->s = s; hit->t = t; hit->region = region; hit->part = part;
  for (i = 0; i < 3; ++i) { hit->c[i] = c[i]; x[i] = w->a[i] + s * w->ab[i]; }
  if (part == 0) for (i = 0; i < 3; ++i) x[i] = w->a[i];
  if (part == 2) for (i = 0; i < 3; ++i) x[i] = w->b[i];
  if (hit->dist > VFM_TOUCH) {
    for (i = 0; i < 3; ++i) hit->u[i] = (x[i] - c[i]) / hit->dist;
  } else {                            /* the face's own normal, toward the free side */
    double n[3];
    vfm_normal(t, n);
    double norm = sqrt(vfm_dot(n, n));
    for (i = 0; i < 3; ++i) hit->u[i] = w->side * n[i] / norm;
  }
}

/* The corners of triangle t. */
static void vfm_corners(int t, const double** v) {
  const int* tri = vfm_triangles + 3 * t;
  v[0] = vfm_vertices + 3 * tri[0]; v[1] = vfm_vertices + 3 * tri[1]; v[2] = vfm_vertices + 3 * tri[2];
}

/* Triangle t's hit between the ends (its closest pair with the segment, the segment's point strictly between a and
 * b, within the cutoff), given the closest points ca, cb of its corners v to a and b: 1 and the hit, or 0. */
static int vfm_pair_hit(const vfm_walk* w, int t, const double* const* v, const double* ca, int ra, const double* cb,
                        int rb, vfm_hit* hit) {
  double c[3], s;
  int region;
  double d2 = vfm_pair(w, t, v, ca, vfm_dist2(w->a, ca), ra, cb, vfm_dist2(w->b, cb), rb, &s, c, &region);
  if (!(s > 0 && s < 1 && d2 <= w->cutoff * w->cutoff)) return 0;
  vfm_make_hit(w, t, 1, s, c, region, d2, hit);
  return 1;
}

/* The same from the triangle alone. */
static int vfm_inner_hit(const vfm_walk* w, int t, vfm_hit* hit) {
  const double* v[3];
  double ca[3], cb[3];
  int ra, rb;
  vfm_corners(t, v);
  vfm_point_triangle(w->a, v[0], v[1], v[2], ca, &ra);
  vfm_point_triangle(w->b, v[0], v[1], v[2], cb, &rb);
  return vfm_pair_hit(w, t, v, ca, ra, cb, rb, hit);
}

/* The point of 2-D triangle v's edges nearest the origin: the triangle's nearest point when it has no area (two
 * corners on one line with ab: a wall parallel to the segment), where vfm_closest_point's face step divides 0 by 0. */
static void vfm_nearest_on_edges(const double* const* v, double* out) {
  double best = INFINITY;
  int e;
  for (e = 0; e < 3; ++e) {
    const double *p = v[e], *q = v[(e + 1) % 3];
    double d[2] = {q[0] - p[0], q[1] - p[1]}, dd = d[0] * d[0] + d[1] * d[1];
    double s = dd > 0 ? vfm_clamp01(-(p[0] * d[0] + p[1] * d[1]) / dd) : 0;
    double x[2] = {p[0] + s * d[0], p[1] + s * d[1]}, r = x[0] * x[0] + x[1] * x[1];
    if (r < best) { best = r; out[0] = x[0]; out[1] = x[1]; }
  }
}

/* Triangle t's (corners v) hit between the ends, deferred (the best-first mode): a pending entry keyed by the
 * distance from the segment's line to the triangle (the least distance of the triangle's projection on the plane
 * normal to ab from the origin), never more than the hit's distance, and at least `floor` (its box's key). When the
 * hit exists, its segment point is a local, so global, least of the distance along the line (convex): the line's
 * closest pair, whose direction is the projection's closest point's, up to rounding; a pending entry whose direction
 * is merged for sure is dropped, now or when it comes out. (`floor`, a box's key, is already lowered for rounding.) */
static void vfm_pending(vfm_walk* w, int t, const double (*plane)[2], double floor) {
  const unsigned char* slot = vfm_corner_slots + 3 * t;
  const double* v[3] = {plane[slot[0]], plane[slot[1]], plane[slot[2]]};
  double origin[2] = {0, 0}, c[2];
  int region;
  vfm_closest_point(2, origin, v[0], v[1], v[2], c, &region);
  if (!(c[0] == c[0] && c[1] == c[1])) vfm_nearest_on_edges(v, c);   /* a projection of no area */
  double line = sqrt(c[0] * c[0] + c[1] * c[1]), key = line * (1 - VFM_LINE_SLACK) - w->slack;
  if (key > w->cutoff) return;        /* its hit, if any, is beyond the cutoff */
  vfm_hit* e = &w->leaf[w->nleaf];
  e->dist = key > floor ? key : floor;
  e->part = 1; e->t = t; e->region = VFM_PENDING; e->s = 0;
  e->u[0] = e->u[1] = e->u[2] = 0;
  if (line >= VFM_SAME_FROM) {        /* s = 1: u is the hit's direction (in e1, e2) */
    e->u[0] = -c[0] / line; e->u[1] = -c[1] / line;
    e->s = 1;
  }
  if (!vfm_merged_for_sure(w, e)) ++w->nleaf;
}

/* Triangle t's hits for the parts of `mask` (between the ends: pending, or computed in the depth-first mode). */
static void vfm_triangle(vfm_walk* w, int t, int mask, double floor, const double (*plane)[2]) {
  const double* v[3];
  double c[2][3];
  int region[2] = {0, 0}, p;
  vfm_hit hit;
  mask &= ~w->done;
  if (mask & (w->successor ? 7 : 5)) vfm_corners(t, v);   /* a pending entry needs only the leaf's projection */
  /* an end's closest point: for its hit, and in the depth-first mode the pair's (none when no part needs it) */
  for (p = 0; p < 3 && (mask & (w->successor ? 7 : 5)); p += 2) {
    if (!(mask & (w->successor ? 3 << (p / 2) : 1 << p))) continue;
    const double* x = p ? w->b : w->a;
    vfm_point_triangle(x, v[0], v[1], v[2], c[p / 2], &region[p / 2]);
    double d2 = vfm_dist2(x, c[p / 2]);
    if (!(mask >> p & 1) || d2 > w->cutoff * w->cutoff) continue;
    vfm_make_hit(w, t, p, p == 2, c[p / 2], region[p / 2], d2, &hit);
    vfm_offer(w, &hit);
  }
  if (!(mask & 2)) return;
  if (!w->successor) vfm_pending(w, t, plane, floor);
  else if (vfm_pair_hit(w, t, v, c[0], region[0], c[1], region[1], &hit)) vfm_offer(w, &hit);
}

/* The pseudo-normal of feature `region` of triangle t. */
static const float* vfm_feature_normal(int t, int region) {
  const int* tri = vfm_triangles + 3 * t;
  if (region == 0) return vfm_face_normals + 3 * t;
  if (region < 4) return vfm_edge_normals + 9 * t + 3 * (region - 1);
  return vfm_vertex_normals + 3 * tri[region - 4];
}

/* +1 when x is on the free side of feature `region` of triangle t (closest point c), else -1. */
static double vfm_side_of(const vfm_walk* w, const double* x, const double* c, int t, int region) {
  double diff[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
  return w->side * vfm_dotf(diff, vfm_feature_normal(t, region)) >= 0 ? 1.0 : -1.0;
}

/* A hit comes out of the queue in order: merged, or kept (the first of an end's part sets its side: it is the
 * end's nearest feature). */
static void vfm_take(vfm_walk* w, const vfm_hit* hit) {
  int p = hit->part;
  if (vfm_done(w, p) || vfm_merged(w, p, hit->u)) return;
  if (w->count[p] == 0 && p != 1) w->part_side[p] = vfm_side_of(w, p ? w->b : w->a, hit->c, hit->t, hit->region);
  w->kept[p][w->count[p]] = *hit;
  if (p == 1) { w->plane[w->count[1]][0] = vfm_dot(hit->u, w->e1); w->plane[w->count[1]][1] = vfm_dot(hit->u, w->e2); }
  vfm_counted(w, p);
}

/* The nearest feature of the mesh to x nearer than sqrt(*best2) (a depth-first search, the nearer child first):
 * updates *best2, *t, *region and c when one is found; of features at the same distance, the one whose point comes
 * first in the order of coordinates (triangles that share an edge or a corner give it at the same distance: the one
 * taken does not depend on the order of the walk, hence of the BVH or of the triangles in the file). */
static void vfm_nearest(const double* x, double* best2, int* t_best, int* r_best, double* near) {
  double y[3], c[3];
  int stack[VFM_STACK], top = 0, i, t, region;
  stack[top++] = 0;
  while (top > 0) {
    int node = stack[--top];
    vfm_local(node, x, y);
    double bound = vfm_point_box(y, vfm_boxes + 15 * node + 12);
    if (!(bound * bound <= *best2)) continue;
    if (vfm_is_leaf(node)) {
      int from = -1 - vfm_nodes[2 * node];
      for (t = from; t < from + vfm_nodes[2 * node + 1]; ++t) {
        const int* tri = vfm_triangles + 3 * t;
        vfm_point_triangle(x, vfm_vertices + 3 * tri[0], vfm_vertices + 3 * tri[1], vfm_vertices + 3 * tri[2], c,
                           &region);
        double d2 = vfm_dist2(x, c);
        if (d2 < *best2 || (d2 == *best2 && vfm_compare_points(c, near) < 0)) {
          *best2 = d2; *t_best = t; *r_best = region;
          for (i = 0; i < 3; ++i) near[i] = c[i];
        }
      }
      continue;
    }
    if (top + 2 > VFM_STACK) continue;   /* unreachable: the builder bounds the depth below VFM_STACK / 2 */
    int left = vfm_nodes[2 * node], right = vfm_nodes[2 * node + 1];
    double yl[3], yr[3];
    vfm_local(left, x, yl);
    vfm_local(right, x, yr);
    int left_nearer = vfm_point_box(yl, vfm_boxes + 15 * left + 12) <= vfm_point_box(yr, vfm_boxes + 15 * right + 12);
    stack[top++] = left_nearer ? right : left;
    stack[top++] = left_nearer ? left : right;
  }
}

/* The side of the points between the ends: that of the first hit's point x, from x's nearest feature, which is the
 * hit's own unless a triangle whose pair with the segment is at an end is nearer to x. */
static void vfm_inner_side(vfm_walk* w) {
  const vfm_hit* first = &w->kept[1][0];
  double x[3], best2, near[3];
  int i, t_best = first->t, r_best = first->region;
  for (i = 0; i < 3; ++i) { x[i] = w->a[i] + first->s * w->ab[i]; near[i] = first->c[i]; }
  best2 = first->dist * first->dist;
  vfm_nearest(x, &best2, &t_best, &r_best, near);
  w->part_side[1] = vfm_side_of(w, x, near, t_best, r_best);
}

/* An end with no hit within the cutoff may still be on the forbidden side, far from the surface (a tool outside a
 * keep-in volume, deep inside a keep-out one): its nearest feature, at whatever distance, is kept when it puts the
 * end on the forbidden side, so that a violated fixture always has a row that asks back. */
static void vfm_far_ends(vfm_walk* w) {
  int p;
  for (p = 0; p < 3; p += 2) {
    if (!(w->parts >> p & 1) || w->count[p] > 0) continue;
    const vfm_near* e = vfm_end_near(w, p);
    if (e->t < 0 || vfm_side_of(w, p ? w->b : w->a, e->c, e->t, e->region) > 0) continue;
    vfm_make_hit(w, e->t, p, p == 2, e->c, e->region, e->d2, &w->kept[p][0]);
    vfm_counted(w, p);
    w->part_side[p] = -1;
  }
}

static int vfm_all_done(const vfm_walk* w) { return (w->done & w->parts) == w->parts; }

static void vfm_leaf(vfm_walk* w, int node, int mask, double floor) {
  int t, j, first = -1 - vfm_nodes[2 * node], count = vfm_nodes[2 * node + 1];
  double plane[3 * VFM_LEAF][2];      /* the leaf's vertices projected on the plane normal to ab, from a */
  if (mask & 2 & ~w->done && !w->successor)
    for (j = 0; j < 3 * count && vfm_leaf_vertices[3 * first + j] >= 0; ++j) {
      const double* v = vfm_vertices + 3 * vfm_leaf_vertices[3 * first + j];
      double d[3] = {v[0] - w->a[0], v[1] - w->a[1], v[2] - w->a[2]};
      plane[j][0] = vfm_dot(d, w->e1); plane[j][1] = vfm_dot(d, w->e2);
    }
  for (t = first; t < first + count; ++t) vfm_triangle(w, t, mask, floor, plane);
}

/* The order of a leaf's entries: by key (a hit's distance, a pending entry's bound), a pending entry before the hits
 * of its key (as a box is), the hits in their order. */
static int vfm_entry_before(const vfm_hit* x, const vfm_hit* y) {
  if (x->dist != y->dist) return x->dist < y->dist;
  if (vfm_is_pending(x) != vfm_is_pending(y)) return vfm_is_pending(x);
  return vfm_is_pending(x) ? x->t < y->t : vfm_before(x, y);
}

/* Whether entry e comes before everything queued (it would come out next). */
static int vfm_ahead(vfm_walk* w, const vfm_hit* e) {
  if (!(e->dist < w->horizon)) return 0;
  vfm_settle(w);
  if (w->size == 0) return 1;
  const vfm_item* top = &w->heap[0];
  if (e->dist != top->key) return e->dist < top->key;
  return top->ref < 0 && (vfm_is_pending(e) || vfm_before(e, &w->slot[-1 - top->ref]));
}

/* A pending entry comes out: its triangle's hit between the ends, unless that part is done or the hit is merged. */
static int vfm_resolve(vfm_walk* w, const vfm_hit* pending, vfm_hit* hit) {
  if (vfm_done(w, 1) || vfm_merged_for_sure(w, pending)) return 0;
  return vfm_inner_hit(w, pending->t, hit) && !vfm_merged(w, 1, hit->u);
}

/* A leaf's entries from `from` on into the queue: each hit that would not be merged, and the pending entries as one
 * run, in order (their slots room first: the run needs them all at once). */
static void vfm_queue_leaf(vfm_walk* w, int from) {
  int i, n = 0, head = -1, *link, s;
  double first = INFINITY;
  for (i = from; i < w->nleaf; ++i) {
    const vfm_hit* e = &w->leaf[i];
    if (!vfm_is_pending(e)) { if (!vfm_merged(w, e->part, e->u)) vfm_queue(w, e); }
    else { ++n; if (e->dist < first) first = e->dist; }
  }
  if (n == 0 || !vfm_room(w, first, n)) return;
  for (i = from; i < w->nleaf; ++i) {
    const vfm_hit* e = &w->leaf[i];
    if (!vfm_is_pending(e)) continue;
    s = vfm_slot(w);
    w->slot[s] = *e;
    for (link = &head; *link >= 0 && !vfm_entry_before(e, &w->slot[*link]); link = &w->slot[*link].next) {}
    w->slot[s].next = *link;
    *link = s;
  }
  vfm_queue_run(w, head);
}

/* The best-first mode's leaf: its entries in order; each that comes before everything queued is taken (a hit) or
 * resolved (a pending entry, its hit put back in order) at once, as it would be when it came out of the queue; the
 * others are queued. */
static void vfm_leaf_hits(vfm_walk* w, int node, int mask, double floor) {
  int i, j, least = 0;
  w->nleaf = 0;
  vfm_leaf(w, node, mask, floor);
  for (i = 1; i < w->nleaf; ++i) if (vfm_entry_before(&w->leaf[i], &w->leaf[least])) least = i;
  if (w->nleaf > 0 && !vfm_ahead(w, &w->leaf[least])) { vfm_queue_leaf(w, 0); return; }   /* none comes out now */
  for (i = 1; i < w->nleaf; ++i)
    for (j = i; j > 0 && vfm_entry_before(&w->leaf[j], &w->leaf[j - 1]); --j) {
      vfm_hit h = w->leaf[j]; w->leaf[j] = w->leaf[j - 1]; w->leaf[j - 1] = h;
    }
  for (i = 0; i < w->nleaf; ++i) {
    vfm_hit hit;
    if (!vfm_ahead(w, &w->leaf[i])) break;
    if (!vfm_is_pending(&w->leaf[i])) { vfm_take(w, &w->leaf[i]); continue; }
    if (!vfm_resolve(w, &w->leaf[i], &hit)) continue;
    for (j = i; j + 1 < w->nleaf && vfm_entry_before(&w->leaf[j + 1], &hit); ++j) w->leaf[j] = w->leaf[j + 1];
    w->leaf[j] = hit;
    --i;
  }
  vfm_queue_leaf(w, i);
}

/* Depth-first mode: the first hit after w->after that would be kept, into w->best (returns whether found). */
static int vfm_next(vfm_walk* w) {
  int stack[VFM_STACK], masks[VFM_STACK], top = 0, mask;
  double key;
  w->successor = 1;
  w->found = 0;
  stack[top] = 0; masks[top++] = w->parts;
  while (top > 0) {
    int node = stack[--top];
    mask = vfm_useful(w, node, masks[top], &key);
    if (!mask || (w->found && key > w->best.dist)) continue;
    if (vfm_is_leaf(node)) { vfm_leaf(w, node, mask, 0); continue; }
    if (top + 2 > VFM_STACK) continue;   /* unreachable: the builder bounds the depth below VFM_STACK / 2 */
    stack[top] = vfm_nodes[2 * node + 1]; masks[top++] = mask;
    stack[top] = vfm_nodes[2 * node]; masks[top++] = mask;
  }
  w->successor = 0;
  return w->found;
}

static void vfm_query(vfm_walk* w, const double* a, const double* b, double cutoff, double side) {
  int i, mask;
  double key;
  w->a = a; w->b = b; w->cutoff = cutoff; w->side = side;
  for (i = 0; i < 3; ++i) { w->ab[i] = b[i] - a[i]; w->count[i] = 0; w->part_side[i] = 1; }
  w->point = a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
  w->parts = w->point ? 1 : 7;
  if (!w->point) {                    /* e1, e2: normal to ab, from the axis least along it */
    const double* z = w->unit;
    double r[3] = {0, 0, 0}, n, extent = 0;
    w->len = sqrt(vfm_dot(w->ab, w->ab));
    for (i = 0; i < 3; ++i) {
      w->unit[i] = w->ab[i] / w->len;
      extent = fmax(extent, fmax(fabs(a[i]), fabs(b[i])));
    }
    w->slack = 1e-15 * (1 + 4 * extent);
    r[fabs(z[0]) <= fabs(z[1]) ? (fabs(z[0]) <= fabs(z[2]) ? 0 : 2) : (fabs(z[1]) <= fabs(z[2]) ? 1 : 2)] = 1;
    w->e1[0] = z[1] * r[2] - z[2] * r[1]; w->e1[1] = z[2] * r[0] - z[0] * r[2]; w->e1[2] = z[0] * r[1] - z[1] * r[0];
    n = sqrt(vfm_dot(w->e1, w->e1));
    for (i = 0; i < 3; ++i) w->e1[i] /= n;
    w->e2[0] = z[1] * w->e1[2] - z[2] * w->e1[1]; w->e2[1] = z[2] * w->e1[0] - z[0] * w->e1[2];
    w->e2[2] = z[0] * w->e1[1] - z[1] * w->e1[0];
  }
  w->total = 0; w->done = 0; w->known = 0;
  w->size = 0; w->used = 0; w->nfree = 0; w->horizon = INFINITY; w->successor = 0; w->taken = 0;
  mask = vfm_useful(w, 0, w->parts, &key);
  vfm_item item = {key, 0, mask};
  int held = mask != 0;               /* an item in hand, not queued: the walk goes on down the nearer child */
  int purged = 0;                     /* the parts done when the queue was last purged */
  while (!vfm_all_done(w)) {
    if (w->done != purged) { vfm_purge(w); purged = w->done; }
    if (!held) {
      vfm_settle(w);
      if (w->size == 0 || w->heap[0].key >= w->horizon) break;
      item = w->heap[0];
      w->taken = 1;
    }
    held = 0;
    if (item.ref < 0) {
      vfm_hit hit = w->slot[-1 - item.ref];
      vfm_release(w, item.ref);
      vfm_take(w, &hit);
      continue;
    }
    if (item.ref >= VFM_NN) {         /* a pending entry: its hit now, taken or queued in order */
      vfm_hit pending = w->slot[item.ref - VFM_NN], hit;
      vfm_free(w, item.ref - VFM_NN);
      vfm_queue_run(w, pending.next);   /* the rest of its run, before its hit is placed */
      if (vfm_resolve(w, &pending, &hit)) {
        if (vfm_ahead(w, &hit)) vfm_take(w, &hit);
        else vfm_queue(w, &hit);
      }
      continue;
    }
    item.mask = vfm_still(w, &item);
    if (!item.mask) continue;
    if (vfm_is_leaf(item.ref)) { vfm_leaf_hits(w, item.ref, vfm_split(w, &item), item.key); continue; }
    mask = item.mask;
    vfm_item child[2];
    for (i = 0; i < 2; ++i) {
      child[i].ref = vfm_nodes[2 * item.ref + i];
      child[i].mask = vfm_useful(w, child[i].ref, mask, &key);
      child[i].key = key > item.key ? key : item.key;
    }
    int near = child[1].key < child[0].key;
    for (i = 0; i < 2; ++i) {         /* the farther child first: the nearer may stay in hand */
      vfm_item* next = &child[i == 0 ? !near : near];
      if (!next->mask || next->key >= w->horizon) continue;
      if (i == 1) {
        vfm_settle(w);
        if (w->size == 0 || next->key <= w->heap[0].key) { item = *next; held = 1; continue; }
      }
      if (vfm_room(w, next->key, 0)) vfm_push(w, *next);
    }
  }
  if (w->horizon < INFINITY) {        /* the queue overflowed: the rest, one kept hit at a time */
    w->after.dist = w->horizon; w->after.part = -1;
    while (!vfm_all_done(w) && vfm_next(w)) {
      vfm_take(w, &w->best);
      w->after = w->best;
    }
  }
  if (w->count[1] > 0) vfm_inner_side(w);
  vfm_far_ends(w);
}

/* The K rows: the first kept hit of each part, then the nearest of the others; in the hits' order. */
static int vfm_rows(const vfm_walk* w, vfm_hit* rows) {
  int next[3] = {0, 0, 0}, n = 0, p, i, j;
  for (p = 0; p < 3; ++p)
    if (w->count[p] > 0 && n < VFM_K) { rows[n++] = w->kept[p][0]; next[p] = 1; }
  while (n < VFM_K) {
    int best = -1;
    for (p = 0; p < 3; ++p)
      if (next[p] < w->count[p] && (best < 0 || vfm_before(&w->kept[p][next[p]], &w->kept[best][next[best]])))
        best = p;
    if (best < 0) break;
    rows[n++] = w->kept[best][next[best]++];
  }
  for (i = 1; i < n; ++i)
    for (j = i; j > 0 && vfm_before(&rows[j], &rows[j - 1]); --j) {
      vfm_hit h = rows[j]; rows[j] = rows[j - 1]; rows[j - 1] = h;
    }
  return n;
}

/* CasADi's compact sparsity of a dense n x m column: {n, m, colind[m + 1], row[n m]}, filled once. */
static casadi_int vfm_dense3[2 + 1 + 1 + 3], vfm_dense2[2 + 1 + 1 + 2], vfm_densek[2 + 1 + 1 + VFM_K],
    vfm_dense3k[2 + VFM_K + 1 + 3 * VFM_K];

static const casadi_int* vfm_dense(casadi_int* sp, casadi_int rows, casadi_int cols) {
  casadi_int j, i;
  sp[0] = rows; sp[1] = cols;
  for (j = 0; j <= cols; ++j) sp[2 + j] = j * rows;
  for (j = 0; j < cols; ++j) for (i = 0; i < rows; ++i) sp[2 + cols + 1 + j * rows + i] = i;
  return sp;
}

VFM_EXPORT casadi_int @NAME@_n_in(void) { return 3; }
VFM_EXPORT casadi_int @NAME@_n_out(void) { return 3; }

VFM_EXPORT const casadi_int* @NAME@_sparsity_in(casadi_int i) {
  return i == 2 ? vfm_dense(vfm_dense2, 2, 1) : vfm_dense(vfm_dense3, 3, 1);
}

VFM_EXPORT const casadi_int* @NAME@_sparsity_out(casadi_int i) {
  return i == 2 ? vfm_dense(vfm_dense3k, 3, VFM_K) : vfm_dense(vfm_densek, VFM_K, 1);
}

/* The walk's memory is the caller's work vector w (CasADi allocates it with the caller's work: once per
 * controller): written before it is read on every call, so no call sees another's. */
VFM_EXPORT int @NAME@_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {
  if (sz_arg) *sz_arg = 3;
  if (sz_res) *sz_res = 3;
  if (sz_iw) *sz_iw = 0;
  if (sz_w) *sz_w = (casadi_int)((sizeof(vfm_walk) + sizeof(casadi_real) - 1) / sizeof(casadi_real));
  return 0;
}

VFM_EXPORT int @NAME@(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem) {
  vfm_walk* walk = (vfm_walk*)w;
  vfm_hit list[VFM_K];
  int i, j, n;
  (void)iw; (void)mem;
  if (!walk) return 1;
  vfm_query(walk, arg[0], arg[1], arg[2][0], arg[2][1]);
  n = vfm_rows(walk, list);
  for (i = 0; i < VFM_K; ++i) {
    double sign = i < n && list[i].dist > VFM_TOUCH ? walk->part_side[list[i].part] : 1.0;
    if (res[0]) res[0][i] = i < n ? sign * list[i].dist : INFINITY;
    if (res[1]) res[1][i] = i < n ? list[i].s : 0;
    if (res[2]) for (j = 0; j < 3; ++j) res[2][3 * i + j] = i < n ? sign * list[i].u[j] : 0;
  }
  return 0;
}
