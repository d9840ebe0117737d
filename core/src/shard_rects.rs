//! Which pixels shard `i` of `n` renders: whole tiles of the driver's fixed tile grid
//! ([`crate::integrator::TILE_SIZE`], aligned to pixel (0, 0)), clipped to the image's pixel
//! bounds, balanced by pixel count. Every pixel belongs to exactly one shard of a partition,
//! and a shard is a few rectangles, each rendered as a crop (crops are bit-identical to the
//! full image), so merged shards reproduce the single render bit for bit.

use crate::geometry::Bounds2i;
use crate::integrator::tiles;
use glam::IVec2;

/// How the tiles are dealt out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum TileLayout {
    /// Consecutive runs of tiles in raster order (a shard is at most three rectangles: the end
    /// of a tile row, whole tile rows, the start of a tile row).
    #[default]
    Rows,
    /// A `columns × rows` grid of rectangular blocks of tiles (`columns × rows = n`, chosen so
    /// that the blocks are as square as the image allows).
    Grid,
}

impl TileLayout {
    pub fn name(self) -> &'static str {
        match self {
            TileLayout::Rows => "rows",
            TileLayout::Grid => "grid",
        }
    }

    pub fn parse(s: &str) -> Option<TileLayout> {
        match s {
            "rows" => Some(TileLayout::Rows),
            "grid" => Some(TileLayout::Grid),
            _ => None,
        }
    }
}

/// The boundaries `cuts[0] = 0 ≤ … ≤ cuts[n] = sizes.len()` that split items of the given
/// sizes into `n` consecutive groups balanced by size: each cut is the item boundary nearest
/// to `i/n` of the total, moved (when there are at least `n` items) so that no group is empty.
fn balanced_cuts(sizes: &[i64], n: u32) -> Vec<usize> {
    let total: i64 = sizes.iter().sum();
    let (n, len) = (n as i64, sizes.len());
    let mut cuts = vec![0usize];
    let (mut k, mut before) = (0usize, 0i64);
    for i in 1..n {
        while k < len && (2 * before + sizes[k]) * n <= 2 * i * total {
            before += sizes[k];
            k += 1;
        }
        let mut cut = k;
        if len as i64 >= n {
            cut = cut.max(cuts[cuts.len() - 1] + 1).min(len - (n - i) as usize);
        }
        cuts.push(cut.max(cuts[cuts.len() - 1]));
    }
    cuts.push(len);
    cuts
}

/// The columns × rows factorisation of `n` whose blocks of a `w × h` image are closest to square.
fn grid_shape(n: u32, w: i64, h: i64) -> (u32, u32) {
    let mut best = (n, 1);
    let mut best_err = f64::INFINITY;
    for c in (1..=n).filter(|c| n.is_multiple_of(*c)) {
        let r = n / c;
        let err = ((w as f64 / c as f64) / (h as f64 / r as f64)).ln().abs();
        if err < best_err {
            best_err = err;
            best = (c, r);
        }
    }
    best
}

/// The pixels of shard `index` of `count` (`index < count`) of the image's `bounds`, as
/// disjoint rectangles in raster order. Shards beyond the number of tiles are empty.
pub fn shard_rects(bounds: Bounds2i, index: u32, count: u32, layout: TileLayout) -> Vec<Bounds2i> {
    if count == 0 || index >= count || bounds.is_empty() {
        return Vec::new();
    }
    let all = tiles(bounds);
    match layout {
        TileLayout::Rows => {
            let sizes: Vec<i64> = all.iter().map(Bounds2i::area).collect();
            let cuts = balanced_cuts(&sizes, count);
            let mine = &all[cuts[index as usize]..cuts[index as usize + 1]];
            // Runs within a tile row become one rectangle; consecutive rows of the same
            // extent are joined.
            let mut rows: Vec<Bounds2i> = Vec::new();
            for t in mine {
                match rows.last_mut() {
                    Some(r) if r.min.y == t.min.y && r.max.x == t.min.x => r.max.x = t.max.x,
                    _ => rows.push(*t),
                }
            }
            let mut out: Vec<Bounds2i> = Vec::new();
            for r in rows {
                match out.last_mut() {
                    Some(o) if o.min.x == r.min.x && o.max.x == r.max.x && o.max.y == r.min.y => o.max.y = r.max.y,
                    _ => out.push(r),
                }
            }
            out
        }
        TileLayout::Grid => {
            let mut xs: Vec<(i32, i32)> = all.iter().map(|t| (t.min.x, t.max.x)).collect();
            let mut ys: Vec<(i32, i32)> = all.iter().map(|t| (t.min.y, t.max.y)).collect();
            xs.sort_unstable();
            xs.dedup();
            ys.sort_unstable();
            ys.dedup();
            let (c, r) = grid_shape(count, bounds.width() as i64, bounds.height() as i64);
            let cx = balanced_cuts(&xs.iter().map(|(a, b)| (b - a) as i64).collect::<Vec<_>>(), c);
            let cy = balanced_cuts(&ys.iter().map(|(a, b)| (b - a) as i64).collect::<Vec<_>>(), r);
            let (i, j) = ((index % c) as usize, (index / c) as usize);
            if cx[i] == cx[i + 1] || cy[j] == cy[j + 1] {
                return Vec::new();
            }
            let min = IVec2::new(xs[cx[i]].0, ys[cy[j]].0);
            let max = IVec2::new(xs[cx[i + 1] - 1].1, ys[cy[j + 1] - 1].1);
            vec![Bounds2i::new(min, max)]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn b(x0: i32, x1: i32, y0: i32, y1: i32) -> Bounds2i {
        Bounds2i::new(IVec2::new(x0, y0), IVec2::new(x1, y1))
    }

    /// Every pixel of the image is in exactly one shard, for both layouts, crops off the tile
    /// grid, and more shards than tiles; shards are balanced to within a tile.
    #[test]
    fn shards_partition_the_image() {
        for bounds in [b(0, 40, 0, 36), b(3, 77, 5, 50), b(0, 16, 0, 16), b(10, 11, 20, 21), b(0, 100, 0, 7)] {
            let tile_count = tiles(bounds).len() as u32;
            for n in [1, 2, 3, 5, 7, 12, 40] {
                for layout in [TileLayout::Rows, TileLayout::Grid] {
                    let mut owner = vec![0u32; bounds.area() as usize];
                    let mut sizes = Vec::new();
                    for i in 0..n {
                        let rects = shard_rects(bounds, i, n, layout);
                        let mut size = 0;
                        for r in &rects {
                            assert_eq!(r.intersect(&bounds), *r, "{r:?} outside {bounds:?}");
                            for p in r.iter() {
                                owner[((p.y - bounds.min.y) * bounds.width() + p.x - bounds.min.x) as usize] += 1;
                            }
                            size += r.area();
                        }
                        assert!(rects.len() <= 3, "{layout:?} {i}/{n} of {bounds:?}: {rects:?}");
                        sizes.push(size);
                    }
                    assert!(owner.iter().all(|&c| c == 1), "{layout:?} {n} shards of {bounds:?}: {owner:?}");
                    if layout == TileLayout::Rows && n <= tile_count {
                        // Balanced: no shard is empty, and shards differ by at most two full tiles.
                        let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
                        assert!(*lo > 0 && hi - lo <= 2 * 256, "{n} shards of {bounds:?}: sizes {sizes:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn rectangles_are_whole_tiles() {
        // 40×36: tiles of 16 in x at 0, 16, 32 (the last 8 wide), in y 0, 16, 32 (4 high).
        let r = shard_rects(b(0, 40, 0, 36), 1, 3, TileLayout::Rows);
        // Pixel counts 256 256 128 / 256 256 128 / 64 64 32, a third of 1440 is 480: the cuts
        // nearest to 480 and 960 are after 512 and 896 pixels.
        assert_eq!(r, vec![b(32, 40, 0, 16), b(0, 16, 16, 32)]);
        assert_eq!(shard_rects(b(0, 40, 0, 36), 2, 3, TileLayout::Rows), vec![b(16, 40, 16, 32), b(0, 40, 32, 36)]);
        assert_eq!(grid_shape(6, 300, 200), (3, 2));
        assert_eq!(grid_shape(7, 300, 200), (7, 1));
        // More shards than tiles: the last ones are empty.
        assert_eq!(shard_rects(b(0, 16, 0, 16), 0, 2, TileLayout::Rows), vec![b(0, 16, 0, 16)]);
        assert_eq!(shard_rects(b(0, 16, 0, 16), 1, 2, TileLayout::Rows), vec![]);
        assert_eq!(shard_rects(b(0, 16, 0, 16), 1, 2, TileLayout::Grid), vec![]);
    }
}
