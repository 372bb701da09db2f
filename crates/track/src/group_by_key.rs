//! [`group_by_key`]: items gathered by a small integer key with a counting sort, into one
//! flat list and offsets, instead of a vector per key.

/// `keyed` (key, item) pairs, keys below `keys`, gathered by key, stably: returns `start`
/// (`keys + 1` offsets) and `items`, key `g`'s items being `items[start[g]..start[g + 1]]` in
/// the order they came.
pub(crate) fn group_by_key(
    keyed: impl Iterator<Item = (usize, usize)>,
    keys: usize,
) -> (Vec<usize>, Vec<usize>) {
    let keyed: Vec<(usize, usize)> = keyed.collect();
    let mut start = vec![0usize; keys + 1];
    for &(g, _) in &keyed {
        start[g + 1] += 1;
    }
    for g in 0..keys {
        start[g + 1] += start[g];
    }
    let mut fill = start.clone();
    let mut items = vec![0usize; keyed.len()];
    for (g, item) in keyed {
        items[fill[g]] = item;
        fill[g] += 1;
    }
    (start, items)
}

#[cfg(test)]
mod tests {
    use super::group_by_key;

    /// Each key's items come back in their input order, empty keys included.
    #[test]
    fn groups_keep_input_order() {
        let keyed = [(2, 10), (0, 11), (2, 12), (3, 13), (0, 14)];
        let (start, items) = group_by_key(keyed.into_iter(), 4);
        assert_eq!(start, [0, 2, 2, 4, 5]);
        assert_eq!(items, [11, 14, 10, 12, 13]);
    }
}
