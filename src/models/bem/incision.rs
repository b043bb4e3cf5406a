//! The myotomy paper's surface incision (its Figs 6-7): after the tool's first contact its
//! path is recorded on the surface, and each time it crosses into a neighbouring polygon the
//! polygon it left is divided along the path.
//!
//! The path runs from vertex to vertex of the divided surface. At the first contact the point
//! becomes a vertex (its triangle divided in three). When the tool leaves the triangle it is
//! in through the edge opposite the path's last vertex `V`, the crossing point `Q` becomes a
//! vertex on that edge, dividing both triangles that share it (so no vertex ever sits on
//! another triangle's edge and the surface stays watertight), and `VQ` is a cut edge: the two
//! triangles beside it are marked as passed over. A crossing within a small fraction of an
//! edge's length from its end goes through that vertex instead (no slivers).
//!
//! The hierarchy (Fig. 7) is each divided triangle's original: [`Incision::origin`] maps every
//! triangle now to the original it lies in, [`Incision::pieces`] an original to its pieces.

use glam::DVec3;

/// A crossing this close to an edge's end (as a fraction of the edge) snaps to the vertex.
const SNAP: f64 = 0.08;
/// Triangles the path may cross in one advance.
const MOST_CROSSINGS: usize = 64;

/// A surface being incised.
#[derive(Debug, Clone)]
pub struct Incision {
    pub vertices: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
    /// Each triangle's original.
    origin: Vec<u32>,
    /// Whether the tool passed over it (it borders a cut edge).
    passed: Vec<bool>,
    /// The cut edges, in the order they were made.
    cuts: Vec<[u32; 2]>,
    /// The path's last vertex and the triangle (incident to it) the tool is in.
    at: Option<(u32, usize)>,
}

impl Incision {
    /// An uncut surface (triangles wound outwards).
    pub fn new(vertices: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Incision {
        let n = triangles.len();
        Incision {
            vertices,
            triangles,
            origin: (0..n as u32).collect(),
            passed: vec![false; n],
            cuts: Vec::new(),
            at: None,
        }
    }

    /// Triangle `t`'s original.
    pub fn origin(&self, t: usize) -> usize {
        self.origin[t] as usize
    }

    /// The triangles now that lie in original `o`.
    pub fn pieces(&self, o: usize) -> Vec<usize> {
        (0..self.triangles.len())
            .filter(|&t| self.origin[t] as usize == o)
            .collect()
    }

    /// The piece of original `o` that `p` projects into (the nearest by centroid when it
    /// projects into none); `o` itself when out of range.
    pub fn piece_at(&self, o: usize, p: DVec3) -> usize {
        let pieces = self.pieces(o);
        if let Some(&t) = pieces.iter().find(|&&t| self.inside(t, p)) {
            return t;
        }
        let centroid = |t: usize| {
            let [a, b, c] = self.corners(t);
            (a + b + c) / 3.0
        };
        pieces
            .into_iter()
            .min_by(|&a, &b| {
                (centroid(a) - p)
                    .length_squared()
                    .total_cmp(&(centroid(b) - p).length_squared())
            })
            .unwrap_or(o)
    }

    /// Whether the tool passed over triangle `t`.
    pub fn passed(&self, t: usize) -> bool {
        self.passed[t]
    }

    /// The cut edges, in order.
    pub fn cuts(&self) -> &[[u32; 2]] {
        &self.cuts
    }

    /// The length of the cut, m.
    pub fn cut_length_m(&self) -> f64 {
        self.cuts
            .iter()
            .map(|&[a, b]| (self.vertices[a as usize] - self.vertices[b as usize]).length())
            .fold(0.0, |sum, l| sum + l)
    }

    /// Lifts the tool: the next contact starts a new path.
    pub fn lift(&mut self) {
        self.at = None;
    }

    fn corners(&self, t: usize) -> [DVec3; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    fn normal(&self, t: usize) -> DVec3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// The tool touches the surface at `p` in triangle `t` (the caller's closest triangle):
    /// the first contact starts the path, later ones extend it, dividing what it crosses.
    pub fn advance(&mut self, t: usize, p: DVec3) {
        if t >= self.triangles.len() || !p.is_finite() {
            return;
        }
        let Some((mut v, mut tri)) = self.at else {
            let v = self.insert_inside(t, p);
            self.at = Some((v, self.triangle_towards(v, p).unwrap_or(t)));
            return;
        };
        for _ in 0..MOST_CROSSINGS {
            let [a, b] = self.opposite(tri, v);
            let n = self.normal(tri);
            let vp = self.vertices[v as usize];
            let (pa, pb) = (self.vertices[a as usize], self.vertices[b as usize]);
            // In the triangle's plane: does V -> p leave through edge ab?
            let target = p - n * (p - vp).dot(n);
            let Some(s) = crossing(vp, target, pa, pb, n) else {
                // p is inside (or the path turned back into V's fan): find V's triangle
                // towards p, if p is beyond this one.
                match self.triangle_towards(v, p) {
                    Some(next) if next != tri && !self.inside(tri, p) => tri = next,
                    _ => break,
                }
                if self.inside(tri, p) {
                    break;
                }
                continue;
            };
            let q = if s < SNAP {
                a
            } else if s > 1.0 - SNAP {
                b
            } else {
                self.split_edge(a, b, pa + (pb - pa) * s)
            };
            self.mark_cut(v, q);
            v = q;
            match self.triangle_towards(v, p) {
                Some(next) => tri = next,
                None => break,
            }
            if self.inside(tri, p) {
                break;
            }
        }
        self.at = Some((v, tri));
    }

    /// Whether `p` projects into triangle `t`.
    fn inside(&self, t: usize, p: DVec3) -> bool {
        let [a, b, c] = self.corners(t);
        let n = (b - a).cross(c - a);
        let side = |u: DVec3, w: DVec3| (w - u).cross(p - u).dot(n) >= -1e-12 * n.length_squared();
        side(a, b) && side(b, c) && side(c, a)
    }

    /// Triangle `t`'s two vertices other than `v`, in its winding order after `v`.
    fn opposite(&self, t: usize, v: u32) -> [u32; 2] {
        let tr = self.triangles[t];
        let k = tr.iter().position(|&x| x == v).unwrap_or(0);
        [tr[(k + 1) % 3], tr[(k + 2) % 3]]
    }

    /// Of the triangles around vertex `v`, the one whose corner at `v` contains the direction
    /// to `p` (each projected on its own plane).
    fn triangle_towards(&self, v: u32, p: DVec3) -> Option<usize> {
        let vp = self.vertices[v as usize];
        let mut best: Option<(f64, usize)> = None;
        for t in 0..self.triangles.len() {
            if !self.triangles[t].contains(&v) {
                continue;
            }
            let [a, b] = self.opposite(t, v);
            let n = self.normal(t);
            let d = p - vp;
            let d = d - n * d.dot(n);
            let (ea, eb) = (
                self.vertices[a as usize] - vp,
                self.vertices[b as usize] - vp,
            );
            // Inside the corner: d is on the inner side of both edges.
            let ina = ea.cross(d).dot(n);
            let inb = d.cross(eb).dot(n);
            let score = ina.min(inb) / (d.length() * ea.length().max(eb.length())).max(1e-300);
            if best.is_none_or(|(s, _)| score > s) {
                best = Some((score, t));
            }
        }
        best.map(|(_, t)| t)
    }

    /// Makes `p` (projected on triangle `t`) a vertex: `t`'s corner when it is that close to
    /// one, a point on an edge (both triangles divided) when that close to one, else a point
    /// inside (`t` divided in three).
    fn insert_inside(&mut self, t: usize, p: DVec3) -> u32 {
        let tr = self.triangles[t];
        let [pa, pb, pc] = self.corners(t);
        let n = (pb - pa).cross(pc - pa);
        let n2 = n.length_squared();
        if n2 <= 0.0 {
            return tr[0];
        }
        let p = p - n * ((p - pa).dot(n) / n2);
        // Barycentric coordinates, clamped into the triangle.
        let l = [
            (pc - pb).cross(p - pb).dot(n) / n2,
            (pa - pc).cross(p - pc).dot(n) / n2,
            (pb - pa).cross(p - pa).dot(n) / n2,
        ]
        .map(|x| x.max(0.0));
        let sum = l[0] + l[1] + l[2];
        let l = l.map(|x| x / sum);
        if let Some(k) = (0..3).find(|&k| l[k] > 1.0 - SNAP) {
            return tr[k];
        }
        let corners = [pa, pb, pc];
        let p = corners[0] * l[0] + corners[1] * l[1] + corners[2] * l[2];
        if let Some(k) = (0..3).find(|&k| l[k] < 0.5 * SNAP) {
            // On the edge opposite corner k.
            let (a, b) = (tr[(k + 1) % 3], tr[(k + 2) % 3]);
            let (qa, qb) = (corners[(k + 1) % 3], corners[(k + 2) % 3]);
            let s = (p - qa).dot(qb - qa) / (qb - qa).length_squared();
            return self.split_edge(a, b, qa + (qb - qa) * s.clamp(0.0, 1.0));
        }
        let [a, b, c] = tr;
        let v = self.vertices.len() as u32;
        self.vertices.push(p);
        let o = self.origin[t];
        self.triangles[t] = [a, b, v];
        for tri in [[b, c, v], [c, a, v]] {
            self.triangles.push(tri);
            self.origin.push(o);
            self.passed.push(false);
        }
        v
    }

    /// Puts a vertex at `q` on edge `ab`, dividing both triangles that share the edge.
    fn split_edge(&mut self, a: u32, b: u32, q: DVec3) -> u32 {
        let v = self.vertices.len() as u32;
        self.vertices.push(q);
        for t in 0..self.triangles.len() {
            let tr = self.triangles[t];
            for k in 0..3 {
                let (x, y, z) = (tr[k], tr[(k + 1) % 3], tr[(k + 2) % 3]);
                if (x == a && y == b) || (x == b && y == a) {
                    // (x, y, z) -> (x, v, z) and (v, y, z).
                    self.triangles[t] = [x, v, z];
                    self.triangles.push([v, y, z]);
                    self.origin.push(self.origin[t]);
                    self.passed.push(self.passed[t]);
                    break;
                }
            }
        }
        v
    }

    /// Records the cut edge `ab` and marks the triangles beside it.
    fn mark_cut(&mut self, a: u32, b: u32) {
        if a == b {
            return;
        }
        self.cuts.push([a, b]);
        for t in 0..self.triangles.len() {
            let tr = self.triangles[t];
            if tr.contains(&a) && tr.contains(&b) {
                self.passed[t] = true;
            }
        }
    }
}

/// Where the segment `v -> p` crosses the segment `a -> b` (all in the plane of normal `n`),
/// as the fraction along `ab`; None if it does not reach it.
fn crossing(v: DVec3, p: DVec3, a: DVec3, b: DVec3, n: DVec3) -> Option<f64> {
    let d = p - v;
    let e = b - a;
    let denom = d.cross(e).dot(n);
    if denom.abs() <= 1e-300 {
        return None;
    }
    // v + t d = a + s e.
    let w = a - v;
    let t = w.cross(e).dot(n) / denom;
    let s = w.cross(d).dot(n) / denom;
    (t > 0.0 && t <= 1.0 && (-1e-9..=1.0 + 1e-9).contains(&s)).then_some(s.clamp(0.0, 1.0))
}

#[cfg(test)]
#[path = "incision_tests.rs"]
mod tests;
