//! Unit tests of linking.

use super::claimants::Claimants;

/// Claimants read back as the tracks pushed, in order, whether none, one or several.
#[test]
fn claimants_hold_what_was_pushed() {
    let mut c = Claimants::default();
    assert!(c.is_empty());
    let mut want = Vec::new();
    for k in [7, 3, 9, 3] {
        c.push(k);
        want.push(k);
        assert_eq!(&c[..], &want[..]);
    }
}
