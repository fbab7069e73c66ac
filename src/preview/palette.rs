//! Colours of the previews: a fixed palette for patches, with neighbouring
//! patches never the same colour, and the fixed colours of singularity
//! indices and valences.

/// Twelve patch colours, far apart in hue and lightness (light enough for
/// black curves to read on them).
pub const PATCH_PALETTE: [[u8; 3]; 12] = [
    [230, 97, 92],
    [93, 165, 218],
    [250, 190, 70],
    [96, 189, 104],
    [178, 118, 178],
    [241, 124, 176],
    [178, 145, 47],
    [120, 210, 210],
    [222, 207, 63],
    [255, 153, 102],
    [160, 160, 255],
    [170, 220, 120],
];

/// Colour of a crossfield singularity of index `+1/n` and a frame
/// singular edge (or quad vertex) of valence 3.
pub const POSITIVE: [u8; 3] = [30, 90, 230];
/// Colour of index `−1/n` and valence 5.
pub const NEGATIVE: [u8; 3] = [220, 30, 30];
/// Colour of every other index or valence.
pub const OTHER: [u8; 3] = [20, 170, 60];
/// Colour of boundary and non-manifold edges in the input preview.
pub const DEFECT: [u8; 3] = [230, 20, 20];
/// Colour of a surface drawn under overlays.
pub const SURFACE: [u8; 3] = [205, 205, 210];
/// Colour of curves, corners and wireframes.
pub const INK: [u8; 3] = [15, 15, 15];

/// Colour of a patch of colour index `k`: the palette, then (for a patch
/// graph needing more than twelve colours) further hues by the golden
/// angle.
pub fn patch_color(k: usize) -> [u8; 3] {
    if let Some(c) = PATCH_PALETTE.get(k) {
        return *c;
    }
    let hue = (k as f64 * 137.507_764) % 360.0;
    hsv_to_rgb(hue, 0.55, 0.92)
}

/// RGB of hue `h` (degrees), saturation `s` and value `v` (in `[0, 1]`).
fn hsv_to_rgb(h: f64, s: f64, v: f64) -> [u8; 3] {
    let c = v * s;
    let hp = h / 60.0;
    let x = c * (1.0 - (hp % 2.0 - 1.0).abs());
    let (r, g, b) = match hp as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    [r, g, b].map(|t| ((t + m) * 255.0).round() as u8)
}

/// A colour index per patch such that patches sharing an edge differ.
///
/// With at most as many patches as palette entries every patch gets its
/// own colour (a cube shows six). Otherwise patches are coloured greedily,
/// most neighbours first, each taking the least-used colour none of its
/// coloured neighbours has; a planar patch graph then needs at most six
/// colours (it always has a vertex of degree ≤ 5), and an index past the
/// palette is still a distinct colour ([`patch_color`]).
/// `neighbours[p]` lists the patches adjacent to `p`.
pub fn color_patches(neighbours: &[Vec<u32>]) -> Vec<usize> {
    let n = neighbours.len();
    if n <= PATCH_PALETTE.len() {
        return (0..n).collect();
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&p| (std::cmp::Reverse(neighbours[p].len()), p));
    let mut color = vec![usize::MAX; n];
    let mut used = vec![0usize; PATCH_PALETTE.len()];
    for p in order {
        let taken: Vec<usize> = neighbours[p].iter().map(|&q| color[q as usize]).filter(|&c| c != usize::MAX).collect();
        let free = (0..used.len()).filter(|c| !taken.contains(c)).min_by_key(|&c| (used[c], c));
        let c = free.unwrap_or_else(|| {
            used.push(0);
            used.len() - 1
        });
        used[c] += 1;
        color[p] = c;
    }
    color
}

/// The colour of a singularity of `index` (a fraction of a turn) of an
/// `n`-symmetric field: `+1/n` (valence 3 for crosses), `−1/n` (valence
/// 5), or another index.
pub fn index_color(index: f64, n: u32) -> [u8; 3] {
    let unit = 1.0 / f64::from(n.max(1));
    if (index - unit).abs() < 1e-6 {
        POSITIVE
    } else if (index + unit).abs() < 1e-6 {
        NEGATIVE
    } else {
        OTHER
    }
}

/// The colour of an irregular quad vertex or a frame singular edge of `valence`.
pub fn valence_color(valence: u32) -> [u8; 3] {
    match valence {
        3 => POSITIVE,
        5 => NEGATIVE,
        _ => OTHER,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn few_patches_all_differ_and_many_never_match_a_neighbour() {
        let ring = |n: usize| -> Vec<Vec<u32>> {
            (0..n).map(|p| vec![((p + n - 1) % n) as u32, ((p + 1) % n) as u32]).collect()
        };
        assert_eq!(color_patches(&ring(6)), vec![0, 1, 2, 3, 4, 5]);
        // A 9×9 grid of patches with diagonal neighbours too (8-connected).
        let id = |i: usize, j: usize| (i * 9 + j) as u32;
        let grid: Vec<Vec<u32>> = (0..81)
            .map(|p| {
                let (i, j) = (p / 9, p % 9);
                let mut out = Vec::new();
                for di in -1i64..=1 {
                    for dj in -1i64..=1 {
                        let (a, b) = (i as i64 + di, j as i64 + dj);
                        if (di, dj) != (0, 0) && (0..9).contains(&a) && (0..9).contains(&b) {
                            out.push(id(a as usize, b as usize));
                        }
                    }
                }
                out
            })
            .collect();
        let colors = color_patches(&grid);
        for (p, ns) in grid.iter().enumerate() {
            for &q in ns {
                assert_ne!(patch_color(colors[p]), patch_color(colors[q as usize]), "patches {p} and {q}");
            }
        }
    }

    #[test]
    fn colours_past_the_palette_are_distinct() {
        let mut all: Vec<[u8; 3]> = (0..40).map(patch_color).collect();
        all.sort_unstable();
        all.dedup();
        assert_eq!(all.len(), 40);
    }
}
