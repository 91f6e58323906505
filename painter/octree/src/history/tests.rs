use super::*;

fn rec(parent: u32, first_child: u32, depth: u8, rgb: [u8; 3], sigma: f32) -> CellRecord {
    CellRecord { parent, first_child, depth, rgb, sigma }
}

#[test]
fn a_step_keeps_every_change_in_its_cheapest_form() {
    let leaf = |rgb, sigma| rec(0, NONE, 3, rgb, sigma);
    let cases = [
        (8, leaf([1, 2, 3], 0.5), leaf([4, 5, 6], 0.75)),              // value: 23 bytes
        (9, CellRecord::FREE, leaf([7, 8, 9], 1.0)),                   // born: 20
        (10, leaf([1, 1, 1], 2.0), CellRecord::FREE),                  // freed: 20
        (11, leaf([1, 1, 1], 2.0), rec(0, 16, 3, [1, 1, 1], 2.0)),     // refined: 36
        (12, rec(0, 16, 3, [0; 3], 0.0), rec(0, 16, 3, [0; 3], -0.0)), // internal: 36
        (13, leaf([1, 1, 1], 2.0), rec(5, NONE, 3, [1, 1, 1], 2.0)),   // reparented: 36
    ];
    let mut step = UndoStep::new(16, 24);
    for (c, b, a) in cases {
        step.push(c, b, a);
    }
    assert_eq!(step.len(), cases.len());
    assert_eq!(step.bytes(), 23 + 20 + 20 + 36 + 36 + 36);
    let mut got: Vec<_> = step.entries().collect();
    got.sort_by_key(|e| e.0);
    for ((c, b, a), (d, e, f)) in cases.iter().zip(&got) {
        assert_eq!(c, d);
        assert!(b.same_bits(e) && a.same_bits(f), "cell {c} came back changed");
    }
}

#[test]
fn born_cells_from_the_old_length_on_go_to_the_tail_in_place() {
    let leaf = |v| rec(0, NONE, 3, [v; 3], 1.0);
    let free = CellRecord::FREE;
    // Born cells one by one, as a document's step gives them; the old
    // used length is 16, so the tail starts at cell 16.
    let mut pushes = vec![
        (8, leaf(1)),  // below the old length (a reused free unit): the list
        (17, leaf(2)), // the tail's first run starts here
        (16, leaf(3)), // before that run: the list
        (18, free),    // free after: the list, where it stays an entry
        (19, leaf(4)), // one past the run's end: a free record, then it
        (28, leaf(5)), // 8 past it: 8 free records, then it
    ];
    pushes.extend((29..34).map(|c| (c, leaf(6)))); // the run holds 8 entries now
    pushes.extend([
        (43, leaf(7)),  // 9 past its end: a second run
        (44, leaf(8)),  // right at its end
        (20, leaf(9)),  // a free place in the first run: the list (runs grow at their end only)
        (39, leaf(10)), // before the last run: the list
        (60, leaf(11)), // a third run would make runs of fewer than 8 entries: the list
    ]);
    let mut step = UndoStep::new(16, 64);
    for &(c, a) in &pushes {
        step.push(c, free, a);
    }
    let runs: Vec<(u32, u32)> = step.tail.iter().map(|r| (r.first, r.end())).collect();
    assert_eq!(runs, [(17, 34), (43, 45)]);
    assert_eq!(step.len(), pushes.len());
    // The list: 6 cells of 20 bytes. The runs: 17 + 2 cells of 7 bytes;
    // spans of one parent and depth: leaf, free (18), leaf (19), free
    // (20-27), leaf (28-33) in the first run, one in the second.
    assert_eq!(step.bytes(), 6 * 20 + 19 * 7 + 6 * 9);
    let got: Vec<u32> = step.entries().map(|e| e.0).collect();
    assert_eq!(got, [8, 16, 18, 20, 39, 60, 17, 19, 28, 29, 30, 31, 32, 33, 43, 44], "the list in its order, then the tail in index order");
    for (c, b, a) in step.entries() {
        let want = pushes.iter().find(|p| p.0 == c).expect("pushed").1;
        assert!(b.same_bits(&free) && a.same_bits(&want), "cell {c}");
    }
}

#[test]
fn packed_runs_give_back_every_record() {
    // Units of 8 siblings, a free unit, parents with children, and
    // spans that change every cell.
    let mut want = Vec::new();
    for u in 0..6u32 {
        for k in 0..8u32 {
            want.push(if u == 2 {
                CellRecord::FREE
            } else {
                rec(u * 3, if (u + k) % 5 == 0 { 100 + 8 * k } else { NONE }, 4 + (u % 2) as u8, [k as u8, u as u8, 7], k as f32 * 0.25)
            });
        }
    }
    want.extend((0..5u32).map(|i| rec(i, NONE, 9, [1; 3], -0.0)));
    let mut p = Packed::default();
    for &r in &want {
        p.push(r);
    }
    assert_eq!(p.len(), want.len());
    let got: Vec<CellRecord> = p.records().collect();
    assert_eq!(got.len(), want.len());
    for (i, (a, b)) in want.iter().zip(&got).enumerate() {
        assert!(a.same_bits(b), "record {i}: {a:?} came back as {b:?}");
    }
    // 5 units and a free unit make 6 spans, then 5 more.
    assert_eq!(p.span_at.len(), 11);
    assert_eq!(p.child_at.len(), want.iter().filter(|r| r.first_child != NONE).count());
    assert_eq!(p.bytes(), want.len() * 7 + 11 * 9 + p.child_at.len() * 8);
    assert_eq!(p.free_records(), 8);
    // A record with a free record's parent and depth but a colour, or
    // children, is no free record.
    p.push(CellRecord { rgb: [0, 0, 1], ..CellRecord::FREE });
    p.push(CellRecord { first_child: 64, ..CellRecord::FREE });
    p.push(CellRecord::FREE);
    assert_eq!(p.free_records(), 9);
}
