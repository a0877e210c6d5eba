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
 *   Unused entries (fewer than K features within the cutoff): d = +inf, s = 0, u = 0.
 *
 * The rows: the features (faces, edges, vertices of the triangles) near the segment, each with the segment's
 * closest point to it and, for a segment, also with each end of the segment (a "part": start, between, end).
 * The walk keeps, per part, the VFM_RAW nearest distinct features (a feature seen through several triangles
 * counts once, keyed by its vertices): a box is skipped when a lower bound of its distance to every part (the
 * ends: exact point-box distances) exceeds the cutoff or that part's VFM_RAW-th distance, or when the box lies
 * within the merging cone (below) of the part's nearest feature seen so far, and farther. Then, nearest first,
 * a feature whose direction u is within VFM_SIMILAR (cosine) of one kept in its part is merged into it, and of
 * what remains the nearest of each part and then the nearest overall make the K rows.
 * Which side of the surface a point of the segment is on comes from the angle-weighted pseudo-normal
 * (Baerentzen & Aanaes 2005) of its nearest feature, which is right at faces, edges and vertices of a closed,
 * consistently oriented mesh; every feature of that part takes that side (the segment's start, its end, and
 * for the points between, the side of the nearest of them). The BVH of axis-aligned boxes (built at compile
 * time) is walked near-child first, with a fixed stack, after the leaves nearest the segment's ends and three
 * inner points (their features fill the pools early, so that the walk prunes early; a feature seen twice counts
 * once); the pools live on the C stack: nothing is allocated, the
 * function is reentrant (iw, w and mem are unused).
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

#define VFM_STACK 128

typedef struct {
  double dist;      /* unsigned distance */
  double s;
  double u[3];      /* unit from the feature to the segment's point (touching: the face's normal times side) */
  long long key;    /* 3 x the feature's key + part */
  int part;         /* where on the segment: 0 its start, 2 its end, 1 between */
  int touching;
} vfm_hit;

typedef struct {
  vfm_hit pool[3][VFM_RAW];   /* per part, the nearest distinct features */
  int count[3];
  double worst[3];     /* the farthest in a full pool (else the cutoff) */
  double nearest[3];   /* per part, the distance of the nearest feature seen, */
  double near_u[3][3]; /* its direction u, */
  double side[3];      /* and +1 when the segment's point is on the free side of it, else -1 */
} vfm_found;

static double vfm_dot(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static double vfm_dotf(const double* a, const float* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static double vfm_clamp01(double x) { return x < 0 ? 0 : (x > 1 ? 1 : x); }

/* Closest point on triangle (a, b, c) to p (Ericson, Real-Time Collision Detection, 5.1.5); region:
 * 0 face, 1 + e edge e (edges (0,1), (1,2), (2,0)), 4 + i vertex i. */
static void vfm_point_triangle(const double* p, const double* a, const double* b, const double* c,
                               double* out, int* region) {
  double ab[3], ac[3], ap[3], bp[3], cp[3];
  int i;
  for (i = 0; i < 3; ++i) { ab[i] = b[i] - a[i]; ac[i] = c[i] - a[i]; ap[i] = p[i] - a[i]; }
  double d1 = vfm_dot(ab, ap), d2 = vfm_dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) { for (i = 0; i < 3; ++i) out[i] = a[i]; *region = 4; return; }
  for (i = 0; i < 3; ++i) bp[i] = p[i] - b[i];
  double d3 = vfm_dot(ab, bp), d4 = vfm_dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) { for (i = 0; i < 3; ++i) out[i] = b[i]; *region = 5; return; }
  double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    double v = d1 / (d1 - d3);
    for (i = 0; i < 3; ++i) out[i] = a[i] + v * ab[i];
    *region = 1; return;
  }
  for (i = 0; i < 3; ++i) cp[i] = p[i] - c[i];
  double d5 = vfm_dot(ab, cp), d6 = vfm_dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) { for (i = 0; i < 3; ++i) out[i] = c[i]; *region = 6; return; }
  double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    double w = d2 / (d2 - d6);
    for (i = 0; i < 3; ++i) out[i] = a[i] + w * ac[i];
    *region = 3; return;
  }
  double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    for (i = 0; i < 3; ++i) out[i] = b[i] + w * (c[i] - b[i]);
    *region = 2; return;
  }
  double denom = 1.0 / (va + vb + vc), v = vb * denom, w = vc * denom;
  for (i = 0; i < 3; ++i) out[i] = a[i] + ab[i] * v + ac[i] * w;
  *region = 0;
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

static long long vfm_edge_key(int va, int vb) {
  int lo = va < vb ? va : vb, hi = va < vb ? vb : va;
  return (long long)VFM_NT + (long long)lo * VFM_NV + hi;
}

static long long vfm_vertex_key(int v) { return (long long)VFM_NT + (long long)VFM_NV * VFM_NV + v; }

/* The pseudo-normal and key of feature `region` of triangle t. */
static const float* vfm_feature(int t, int region, long long* key) {
  const int* tri = vfm_triangles + 3 * t;
  if (region == 0) { *key = t; return vfm_face_normals + 3 * t; }
  if (region < 4) {
    int e = region - 1;
    *key = vfm_edge_key(tri[e], tri[(e + 1) % 3]);
    return vfm_edge_normals + 9 * t + 3 * e;
  }
  *key = vfm_vertex_key(tri[region - 4]);
  return vfm_vertex_normals + 3 * tri[region - 4];
}

/* Closest pair between segment a b and triangle t: segment parameter s, triangle point c, feature region; also
 * each end's own closest point (ends[0..2] for a, ends[3..5] for b), region and squared distance. */
typedef struct {
  double s, c[3], dist;
  int region;
  double end_c[2][3], end_d2[2];
  int end_region[2];
} vfm_pair;

static void vfm_segment_triangle(const double* a, const double* b, int point, int t, vfm_pair* out) {
  const int* tri = vfm_triangles + 3 * t;
  const double* v[3] = {vfm_vertices + 3 * tri[0], vfm_vertices + 3 * tri[1], vfm_vertices + 3 * tri[2]};
  const float* n = vfm_face_normals + 3 * t;
  double best, c[3], x[3];
  int i, e, region;
  for (e = 0; e < 2 - point; ++e) {   /* each end of the segment to the triangle */
    const double* p = e ? b : a;
    vfm_point_triangle(p, v[0], v[1], v[2], out->end_c[e], &out->end_region[e]);
    out->end_d2[e] = 0;
    for (i = 0; i < 3; ++i) out->end_d2[e] += (p[i] - out->end_c[e][i]) * (p[i] - out->end_c[e][i]);
  }
  e = !point && out->end_d2[1] < out->end_d2[0];
  best = out->end_d2[e];
  out->s = e; out->region = out->end_region[e];
  for (i = 0; i < 3; ++i) out->c[i] = out->end_c[e][i];
  if (point) { out->dist = sqrt(best); return; }
  /* the segment through the face: distance 0 */
  double ab[3], da = 0, db = 0;
  for (i = 0; i < 3; ++i) { ab[i] = b[i] - a[i]; da += (a[i] - v[0][i]) * n[i]; db += (b[i] - v[0][i]) * n[i]; }
  if (da * db < 0) {
    double s = da / (da - db);
    for (i = 0; i < 3; ++i) x[i] = a[i] + s * ab[i];
    vfm_point_triangle(x, v[0], v[1], v[2], c, &region);
    if (region == 0) {
      out->s = s; out->region = 0; out->dist = 0;
      for (i = 0; i < 3; ++i) out->c[i] = x[i];
      return;
    }
  }
  /* the segment to an edge of the triangle */
  for (e = 0; e < 3; ++e) {
    const double *p = v[e], *q = v[(e + 1) % 3];
    double s, t2;
    vfm_segment_segment(a, b, p, q, &s, &t2);
    double d2 = 0;
    for (i = 0; i < 3; ++i) {
      x[i] = a[i] + s * ab[i];
      c[i] = p[i] + t2 * (q[i] - p[i]);
      d2 += (x[i] - c[i]) * (x[i] - c[i]);
    }
    if (d2 < best) {
      best = d2; out->s = s;
      out->region = t2 <= 0 ? 4 + e : (t2 >= 1 ? 4 + (e + 1) % 3 : 1 + e);
      for (i = 0; i < 3; ++i) out->c[i] = c[i];
    }
  }
  out->dist = sqrt(best);
}

/* Keep `hit` in its part's pool of the VFM_RAW nearest distinct features. */
static void vfm_keep(vfm_found* found, const vfm_hit* hit) {
  int p = hit->part, i, n = found->count[p];
  vfm_hit* pool = found->pool[p];
  if (hit->dist >= found->worst[p]) return;
  for (i = 0; i < n; ++i) if (pool[i].key == hit->key) return;
  if (n < VFM_RAW) {
    pool[found->count[p]++] = *hit;
    if (found->count[p] < VFM_RAW) return;
  } else {
    int far = 0;
    for (i = 1; i < n; ++i) if (pool[i].dist > pool[far].dist) far = i;
    pool[far] = *hit;
  }
  found->worst[p] = 0;
  for (i = 0; i < VFM_RAW; ++i) if (pool[i].dist > found->worst[p]) found->worst[p] = pool[i].dist;
}

static double vfm_point_box(const double* x, const double* lo, const double* hi) {
  double d2 = 0;
  int i;
  for (i = 0; i < 3; ++i) {
    double g = x[i] < lo[i] ? lo[i] - x[i] : (x[i] > hi[i] ? x[i] - hi[i] : 0);
    d2 += g * g;
  }
  return sqrt(d2);
}

/* A lower bound of the distance between box `node` and the segment: the larger of the distance between the
 * box and the segment's own box, and the distance from the segment to the box's centre less its half-diagonal. */
static double vfm_box_bound(int node, const double* a, const double* b) {
  const double* lo = vfm_boxes + 6 * node;
  const double* hi = lo + 3;
  double gap2 = 0, centre[3], half2 = 0, i_s;
  int i;
  for (i = 0; i < 3; ++i) {
    double slo = a[i] < b[i] ? a[i] : b[i], shi = a[i] < b[i] ? b[i] : a[i];
    double g = slo > hi[i] ? slo - hi[i] : (lo[i] > shi ? lo[i] - shi : 0);
    gap2 += g * g;
    centre[i] = 0.5 * (lo[i] + hi[i]);
    half2 += 0.25 * (hi[i] - lo[i]) * (hi[i] - lo[i]);
  }
  double ab[3], ac[3], ab2 = 0, proj = 0;
  for (i = 0; i < 3; ++i) { ab[i] = b[i] - a[i]; ac[i] = centre[i] - a[i]; ab2 += ab[i] * ab[i]; proj += ab[i] * ac[i]; }
  i_s = ab2 > 0 ? vfm_clamp01(proj / ab2) : 0;
  double r2 = 0;
  for (i = 0; i < 3; ++i) { double x = ac[i] - i_s * ab[i]; r2 += x * x; }
  double sphere = sqrt(r2) - sqrt(half2), gap = sqrt(gap2);
  return sphere > gap ? sphere : gap;
}

/* The hit of feature `region` of triangle t, closest point c, for the segment's point at s (part: 0 the start,
 * 2 the end, 1 between). The side of the point is read from the pseudo-normal of its nearest feature only (the
 * theorem holds there; a feature on the far side of a thin structure would say "through"). */
static void vfm_offer(int t, const double* a, const double* b, double s, const double* c, int region, double dist,
                      double side, vfm_found* found) {
  double diff[3];
  int i;
  vfm_hit hit;
  const float* normal = vfm_feature(t, region, &hit.key);
  int part = s <= 0 ? 0 : (s >= 1 ? 2 : 1);
  hit.key = 3 * hit.key + part;
  hit.part = part;
  for (i = 0; i < 3; ++i) diff[i] = a[i] + s * (b[i] - a[i]) - c[i];
  int nearest = dist < found->nearest[part];
  if (nearest) {
    found->nearest[part] = dist;
    found->side[part] = side * vfm_dotf(diff, normal) >= 0 ? 1.0 : -1.0;
  }
  hit.dist = dist;
  hit.s = s;
  hit.touching = dist <= 1e-12;
  if (!hit.touching) {
    for (i = 0; i < 3; ++i) hit.u[i] = diff[i] / dist;
  } else {                            /* the face's own normal, toward the free side */
    const float* face = vfm_face_normals + 3 * t;
    double norm = sqrt((double)face[0] * face[0] + (double)face[1] * face[1] + (double)face[2] * face[2]);
    for (i = 0; i < 3; ++i) hit.u[i] = side * face[i] / norm;
  }
  if (nearest) for (i = 0; i < 3; ++i) found->near_u[part][i] = hit.u[i];
  vfm_keep(found, &hit);
}

/* Triangle t's hits: the segment's closest pair, and each end's own closest point (a segment parallel to a face
 * is held at both ends, so that it cannot turn into it about the one point a single row would hold). */
static void vfm_consider(int t, const double* a, const double* b, int point, double cutoff, double side,
                         vfm_found* found) {
  vfm_pair pair;
  int e;
  vfm_segment_triangle(a, b, point, t, &pair);
  if (pair.dist > cutoff) return;
  vfm_offer(t, a, b, pair.s, pair.c, pair.region, pair.dist, side, found);
  if (point) return;
  for (e = 0; e < 2; ++e)
    if (pair.s != e && pair.end_d2[e] <= cutoff * cutoff)
      vfm_offer(t, a, b, e, pair.end_c[e], pair.end_region[e], sqrt(pair.end_d2[e]), side, found);
}

/* Whether every hit of part p from a box (centre m, half-diagonal r) would be merged into the part's nearest
 * hit: seen from the point x of the segment (v = x - m, for the points between: v radial to the segment's axis),
 * the box lies within the cone of half-angle acos(VFM_SIMILAR) around that hit's direction, and no nearer. */
static int vfm_dominated(const vfm_found* found, int p, const double* v, double r) {
  double len = sqrt(vfm_dot(v, v));
  if (!(len > r) || len - r < found->nearest[p]) return 0;
  double c = vfm_dot(found->near_u[p], v) / len;
  double spread = acos(c > 1 ? 1 : (c < -1 ? -1 : c)) + asin(r / len);
  return spread <= acos(VFM_SIMILAR);
}

/* Whether box `node` may hold a feature some part keeps: nearer than the part's cutoff or VFM_RAW-th feature
 * (the ends: exact point-box distances), and not dominated. */
static int vfm_worth(int node, const double* a, const double* b, int point, const vfm_found* found) {
  const double* lo = vfm_boxes + 6 * node;
  const double* hi = lo + 3;
  double m[3], va[3], vb[3], vr[3], ab[3], r2 = 0, ab2 = 0, t = 0;
  int i;
  for (i = 0; i < 3; ++i) {
    m[i] = 0.5 * (lo[i] + hi[i]);
    r2 += 0.25 * (hi[i] - lo[i]) * (hi[i] - lo[i]);
    va[i] = a[i] - m[i]; vb[i] = b[i] - m[i]; ab[i] = b[i] - a[i];
    ab2 += ab[i] * ab[i]; t -= va[i] * ab[i];
  }
  double r = sqrt(r2);
  if (vfm_point_box(a, lo, hi) < found->worst[0] && !vfm_dominated(found, 0, va, r)) return 1;
  if (point) return 0;
  if (vfm_point_box(b, lo, hi) < found->worst[2] && !vfm_dominated(found, 2, vb, r)) return 1;
  if (!(vfm_box_bound(node, a, b) < found->worst[1])) return 0;
  t = ab2 > 0 ? t / ab2 : 0;              /* the axis point nearest the centre: the radial vector */
  for (i = 0; i < 3; ++i) vr[i] = va[i] + t * ab[i];
  return t <= 0 || t >= 1 || !vfm_dominated(found, 1, vr, r);
}

static void vfm_query(const double* a, const double* b, double cutoff, double side, vfm_found* found) {
  int stack[VFM_STACK], top = 0, i;
  int point = a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
  for (i = 0; i < 3; ++i) {
    found->count[i] = 0; found->worst[i] = cutoff; found->nearest[i] = INFINITY; found->side[i] = 1;
  }
  for (i = 0; i < (point ? 1 : 5); ++i) {   /* seed the pools: the leaves nearest the ends and 3 inner points */
    double x[3], f = i == 0 ? 0 : (i == 1 ? 1 : 0.25 * (i - 1));
    int j, node = 0;
    for (j = 0; j < 3; ++j) x[j] = a[j] + f * (b[j] - a[j]);
    while (vfm_nodes[2 * node] >= 0) {
      int first = vfm_nodes[2 * node], second = vfm_nodes[2 * node + 1];
      double df = vfm_point_box(x, vfm_boxes + 6 * first, vfm_boxes + 6 * first + 3);
      double ds = vfm_point_box(x, vfm_boxes + 6 * second, vfm_boxes + 6 * second + 3);
      node = df <= ds ? first : second;
    }
    for (j = -1 - vfm_nodes[2 * node]; j < -1 - vfm_nodes[2 * node] + vfm_nodes[2 * node + 1]; ++j)
      vfm_consider(j, a, b, point, cutoff, side, found);
  }
  stack[top++] = 0;
  while (top > 0) {
    int node = stack[--top];
    if (!vfm_worth(node, a, b, point, found)) continue;
    int first = vfm_nodes[2 * node], second = vfm_nodes[2 * node + 1];
    if (first < 0) {                  /* a leaf: triangles -1 - first ... + second */
      int t;
      for (t = -1 - first; t < -1 - first + second; ++t) vfm_consider(t, a, b, point, cutoff, side, found);
      continue;
    }
    if (top + 2 > VFM_STACK) continue;   /* unreachable: the builder bounds the depth below VFM_STACK */
    double bf = vfm_box_bound(first, a, b), bs = vfm_box_bound(second, a, b);
    stack[top++] = bf <= bs ? second : first;   /* the nearer child is popped first */
    stack[top++] = bf <= bs ? first : second;
  }
}

/* The K rows from the pools: per part nearest first, a feature within VFM_SIMILAR of a kept one is merged into
 * it; then the nearest of each part, then the nearest of the rest. */
static int vfm_rows(vfm_found* found, vfm_hit* rows) {
  vfm_hit kept[3 * VFM_RAW];
  int n = 0, p, i, j, k, chosen = 0;
  for (p = 0; p < 3; ++p) {
    vfm_hit* pool = found->pool[p];
    int m = found->count[p], first = n;
    for (i = 1; i < m; ++i)
      for (j = i; j > 0 && pool[j].dist < pool[j - 1].dist; --j) { vfm_hit h = pool[j]; pool[j] = pool[j - 1]; pool[j - 1] = h; }
    for (i = 0; i < m; ++i) {
      for (k = first; k < n && vfm_dot(kept[k].u, pool[i].u) <= VFM_SIMILAR; ++k) {}
      if (k == n) kept[n++] = pool[i];
    }
    if (n > first && chosen < VFM_K) { rows[chosen++] = kept[first]; kept[first].dist = -1; }
  }
  while (chosen < VFM_K) {
    int best = -1;
    for (k = 0; k < n; ++k) if (kept[k].dist >= 0 && (best < 0 || kept[k].dist < kept[best].dist)) best = k;
    if (best < 0) break;
    rows[chosen++] = kept[best];
    kept[best].dist = -1;
  }
  for (i = 1; i < chosen; ++i)       /* nearest first: rows keep a stable order */
    for (j = i; j > 0 && rows[j].dist < rows[j - 1].dist; --j) { vfm_hit h = rows[j]; rows[j] = rows[j - 1]; rows[j - 1] = h; }
  return chosen;
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

VFM_EXPORT int @NAME@_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw, casadi_int* sz_w) {
  if (sz_arg) *sz_arg = 3;
  if (sz_res) *sz_res = 3;
  if (sz_iw) *sz_iw = 0;
  if (sz_w) *sz_w = 0;
  return 0;
}

VFM_EXPORT int @NAME@(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w, int mem) {
  vfm_found found;
  vfm_hit list[VFM_K];
  int i, j, n;
  (void)iw; (void)w; (void)mem;
  vfm_query(arg[0], arg[1], arg[2][0], arg[2][1], &found);
  n = vfm_rows(&found, list);
  for (i = 0; i < VFM_K; ++i) {
    double sign = i < n && !list[i].touching ? found.side[list[i].part] : 1.0;
    if (res[0]) res[0][i] = i < n ? sign * list[i].dist : INFINITY;
    if (res[1]) res[1][i] = i < n ? list[i].s : 0;
    if (res[2]) for (j = 0; j < 3; ++j) res[2][3 * i + j] = i < n ? sign * list[i].u[j] : 0;
  }
  return 0;
}
