//! Graph colouring of constraints: constraints of one colour share no particle, so a colour's
//! projections can run in any order, or all at once on a GPU, with the same result. The CPU's
//! Gauss-Seidel sweeps take the constraints colour by colour (each colour in its given
//! order), which is the order the GPU's dispatches take them: one algorithm on both.

/// Each constraint's colour, greedily in the given order: the smallest colour no earlier
/// constraint on any of its particles has. Deterministic; a mesh's edges take about 2 x its
/// largest valence colours at most.
pub fn greedy<T: AsRef<[u32]>>(particles: &[T]) -> Vec<u32> {
    // Per particle, the colours its constraints have taken (a bit each, the first 64; beyond
    // that a list).
    let mut used: std::collections::HashMap<u32, (u64, Vec<u32>)> =
        std::collections::HashMap::new();
    let mut out = Vec::with_capacity(particles.len());
    for ends in particles {
        let ends = ends.as_ref();
        let mut colour = 0u32;
        loop {
            let taken = ends.iter().any(|i| {
                used.get(i).is_some_and(|(bits, more)| {
                    if colour < 64 {
                        bits & (1u64 << colour) != 0
                    } else {
                        more.contains(&colour)
                    }
                })
            });
            if !taken {
                break;
            }
            colour += 1;
        }
        for &i in ends {
            let e = used.entry(i).or_default();
            if colour < 64 {
                e.0 |= 1u64 << colour;
            } else {
                e.1.push(colour);
            }
        }
        out.push(colour);
    }
    out
}

/// The permutation that sorts items by colour, keeping the given order within a colour.
pub fn order(colours: &[u32]) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..colours.len()).collect();
    idx.sort_by_key(|&k| colours[k]);
    idx
}

/// `items` and their colours sorted by colour (stable): the projection order.
pub fn sorted<T: Clone, const K: usize>(
    items: &[T],
    particles: impl Fn(&T) -> [u32; K],
) -> (Vec<T>, Vec<u32>) {
    let ends: Vec<[u32; K]> = items.iter().map(&particles).collect();
    let colours = greedy(&ends);
    let idx = order(&colours);
    (
        idx.iter().map(|&k| items[k].clone()).collect(),
        idx.iter().map(|&k| colours[k]).collect(),
    )
}

/// The index ranges of each colour in a list sorted by colour: `(colour, first, end)`.
pub fn ranges(colours: &[u32]) -> Vec<(u32, usize, usize)> {
    let mut out = Vec::new();
    let mut first = 0;
    for k in 1..=colours.len() {
        if k == colours.len() || colours[k] != colours[first] {
            out.push((colours[first], first, k));
            first = k;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_two_constraints_of_a_colour_share_a_particle() {
        // The edges of a 6 x 6 grid of particles with its diagonals.
        let mut edges = Vec::new();
        let id = |i: u32, j: u32| i * 6 + j;
        for i in 0..6 {
            for j in 0..6 {
                if j + 1 < 6 {
                    edges.push([id(i, j), id(i, j + 1)]);
                }
                if i + 1 < 6 {
                    edges.push([id(i, j), id(i + 1, j)]);
                }
                if i + 1 < 6 && j + 1 < 6 {
                    edges.push([id(i, j), id(i + 1, j + 1)]);
                }
            }
        }
        let (sorted_edges, colours) = sorted(&edges, |e| *e);
        assert_eq!(sorted_edges.len(), edges.len());
        for (c, first, end) in ranges(&colours) {
            let mut seen = std::collections::HashSet::new();
            for e in &sorted_edges[first..end] {
                assert!(
                    e.iter().all(|&p| seen.insert(p)),
                    "colour {c} repeats a particle"
                );
            }
        }
        // Valence 6 inside: greedy needs at least 6 colours and at most 2 x 6 - 1.
        let n = ranges(&colours).len();
        assert!((6..=11).contains(&n), "{n} colours");
        // Within a colour, the given order is kept.
        for (_, first, end) in ranges(&colours) {
            let pos: Vec<usize> = sorted_edges[first..end]
                .iter()
                .map(|e| edges.iter().position(|f| f == e).expect("an edge"))
                .collect();
            assert!(pos.windows(2).all(|w| w[0] < w[1]));
        }
    }

    #[test]
    fn colours_past_sixty_four_still_keep_apart() {
        // 70 constraints on one particle: 70 colours, one each.
        let star: Vec<[u32; 2]> = (1..=70).map(|k| [0, k]).collect();
        let c = greedy(&star);
        assert_eq!(c, (0..70).collect::<Vec<u32>>());
    }
}
