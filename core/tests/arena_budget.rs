//! Arena budgets of the shipped blobs (`models/<variant>/depthor.dblob`) at their native sizes:
//! the bytes [`Memory::Streamed`] (the default plan) and [`Memory::Whole`] need, printed with
//! the real-time engine issue's goals, and a ceiling per variant that fails if the plan grows.
//! `cargo test -p depthor-core --test arena_budget -- --nocapture` prints the table.

use depthor_core::blob::parse;
use depthor_core::engine::{plan_with, plan_with_into, Fusion, Io, Memory, Plan};

/// (variant, goal bytes, ceiling bytes: the streamed plan as last measured, which the planner
/// must not exceed; +16 B since the conv scratch records which input row each row slot holds;
/// − 57 600 B for mcu_lite, − 64 B for mcu, − 32 B for phone since ops may be deferred to just
/// before their first reader, `Plan::order`; mcu_lite − 14 416 B more since a conv reads a concat
/// with an int16 part in place and the placement also starts from the size × lifetime order).
const BUDGETS: [(&str, usize, usize); 3] = [
    ("mcu", 384 * 1024, CEIL_MCU),
    ("mcu_lite", 384 * 1024, CEIL_MCU_LITE),
    ("phone", 2 * 1024 * 1024, CEIL_PHONE),
];
const CEIL_MCU: usize = 384_127;
/// The firmware's default blob (firmware-sim `model::MCU_LITE_ARENA_BYTES` reserves this, +1).
const CEIL_MCU_LITE: usize = 289_199;
const CEIL_PHONE: usize = 1_672_239;

#[test]
fn shipped_blobs_stay_within_their_arena_ceilings() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    println!("| variant | H×W | streamed arena (B) | whole arena (B) | persistent (B) | goal (B) | ceiling (B) |");
    println!("|---|---|---|---|---|---|---|");
    for (variant, goal, ceiling) in BUDGETS {
        let path = root.join("models").join(variant).join("depthor.dblob");
        let blob = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let g = parse(&blob).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let (h, w) = (g.height, g.width);
        let s = plan_with(&g, h, w, Memory::Streamed).unwrap();
        let whole = plan_with(&g, h, w, Memory::Whole).unwrap();
        println!(
            "| {variant} | {h}×{w} | {} | {} | {} | {goal} | {ceiling} |",
            s.arena_bytes(),
            whole.arena_bytes(),
            s.persistent_bytes()
        );
        assert!(s.arena_bytes() <= whole.arena_bytes());
        assert!(
            s.arena_bytes() <= goal,
            "{variant}: arena {} B is over the goal {goal} B",
            s.arena_bytes()
        );
        assert!(
            s.arena_bytes() <= ceiling,
            "{variant}: arena {} B grew past its ceiling {ceiling} B",
            s.arena_bytes()
        );
        // With the frame buffers in the arena (Io::Arena) the staging areas fit beside the
        // inputs at step 0: no byte more, but for the f32 output area where the refinement
        // writes the output (mcu, phone; not mcu_lite, whose output is an upsample's).
        let mut staged = Plan::empty();
        plan_with_into(&mut staged, &g, (h, w), Memory::Streamed, Io::Arena).unwrap();
        let tail = if s.output_in_arena() { 0 } else { 4 * h * w };
        assert_eq!(staged.output_tail_bytes(), tail, "{variant}");
        assert!(
            staged.arena_bytes() <= ceiling + tail,
            "{variant}: arena with staged I/O {} B grew past its ceiling {ceiling} B",
            staged.arena_bytes()
        );
    }
}

/// [`Memory::Budget`] keeps the least fused plan that fits: the smallest plan at the goal, a
/// less fused one when the budget allows it, and never more bytes than the budget where any
/// plan fits.
#[test]
fn budget_plans_fit_their_budget() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for (variant, goal, _) in BUDGETS {
        let blob = std::fs::read(root.join("models").join(variant).join("depthor.dblob")).unwrap();
        let g = parse(&blob).unwrap();
        let (h, w) = (g.height, g.width);
        let smallest = plan_with(&g, h, w, Memory::Streamed).unwrap();
        assert_eq!(smallest.fusion(), Fusion::All, "{variant}");
        let at_goal = plan_with(&g, h, w, Memory::Budget(goal)).unwrap();
        assert!(at_goal.arena_bytes() <= goal, "{variant}");
        let roomy = plan_with(&g, h, w, Memory::Budget(usize::MAX)).unwrap();
        assert_eq!(roomy.fusion(), Fusion::None, "{variant}");
        let affinities =
            plan_with(&g, h, w, Memory::Budget(smallest.arena_bytes() * 3 / 2)).unwrap();
        println!(
            "{variant}: smallest {} B ({:?}); budget {} B → {} B ({:?}); unlimited → {} B ({:?})",
            smallest.arena_bytes(),
            smallest.fusion(),
            smallest.arena_bytes() * 3 / 2,
            affinities.arena_bytes(),
            affinities.fusion(),
            roomy.arena_bytes(),
            roomy.fusion()
        );
        assert!(affinities.arena_bytes() <= smallest.arena_bytes() * 3 / 2);
        assert_ne!(
            affinities.fusion(),
            Fusion::All,
            "{variant}: 1.5× the smallest allows less fusion"
        );
    }
}

/// Where the streamed plan peaks: per step, the live bytes and the largest live buffers (of the
/// shipped blobs, or of the blob at `$ARENA_BLOB`).
#[test]
#[ignore = "diagnostic: [ARENA_BLOB=path] cargo test -p depthor-core --test arena_budget -- --ignored --nocapture"]
fn where_the_arena_peaks() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let paths: Vec<std::path::PathBuf> = match std::env::var_os("ARENA_BLOB") {
        Some(p) => vec![p.into()],
        None => BUDGETS
            .iter()
            .map(|(v, ..)| root.join("models").join(v).join("depthor.dblob"))
            .collect(),
    };
    for path in paths {
        let variant = path.display();
        let blob = std::fs::read(&path).unwrap();
        let g = parse(&blob).unwrap();
        let p = plan_with(&g, g.height, g.width, Memory::Streamed).unwrap();
        let bufs: Vec<_> = p.buffers().collect();
        let n_t = g.tensors.len();
        let mut steps: Vec<(usize, usize)> = (0..=g.ops.len() + 1)
            .map(|s| {
                let live = bufs
                    .iter()
                    .filter(|(b, _)| b.bytes > 0 && b.first <= s && s <= b.last)
                    .map(|(b, _)| b.bytes)
                    .sum();
                (live, s)
            })
            .collect();
        steps.sort_unstable_by(|a, b| b.cmp(a));
        println!(
            "{variant}: arena {} B (activations {} B); whole plan {} B",
            p.arena_bytes(),
            p.activation_bytes(),
            plan_with(&g, g.height, g.width, Memory::Whole)
                .unwrap()
                .arena_bytes()
        );
        for &(live, s) in steps.iter().take(6) {
            let op = s.checked_sub(1).and_then(|i| g.ops.get(i));
            let mut here: Vec<(usize, usize)> = bufs
                .iter()
                .enumerate()
                .filter(|(_, (b, _))| b.bytes > 0 && b.first <= s && s <= b.last)
                .map(|(i, (b, _))| (b.bytes, i))
                .collect();
            here.sort_unstable_by(|a, b| b.cmp(a));
            let names: Vec<String> = here
                .iter()
                .take(5)
                .map(|&(b, i)| {
                    if i < n_t {
                        format!("t{i}:{b}")
                    } else {
                        format!("scratch{}:{b}", i - n_t)
                    }
                })
                .collect();
            println!(
                "  step {s} (op code {:?}): live {live} B: {}",
                op.map(|o| o.code),
                names.join(" ")
            );
        }
    }
}

#[test]
#[ignore = "diagnostic"]
fn concat_quantisation() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for (variant, ..) in BUDGETS {
        let blob = std::fs::read(root.join("models").join(variant).join("depthor.dblob")).unwrap();
        let g = parse(&blob).unwrap();
        let mut readers = vec![0; g.tensors.len()];
        for op in g.ops.iter() {
            for &i in &op.inputs {
                readers[i as usize] += 1;
            }
        }
        for (i, op) in g.ops.iter().enumerate() {
            if op.code == depthor_core::blob::format::opcode::CONCAT {
                let oq = g.tensors[op.output as usize].q;
                let ins: Vec<String> = op
                    .inputs
                    .iter()
                    .map(|&t| {
                        let q = g.tensors[t as usize].q;
                        format!("t{t}(same q {}, readers {})", q == oq, readers[t as usize])
                    })
                    .collect();
                println!(
                    "{variant} op {i}: out t{} readers {} <- {}",
                    op.output,
                    readers[op.output as usize],
                    ins.join(", ")
                );
            }
        }
    }
}
