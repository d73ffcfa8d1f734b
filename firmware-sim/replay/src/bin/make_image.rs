//! `make-image [--frames N] OUT`: writes a replay image of `N` (default 5) synthetic `mcu`
//! frames ([`depthor_replay::synthetic`]). Stand-in until `depthor firmware-image` converts
//! recordings.
//!
//! `make-image --adversarial OUT`: the adversarial frames of the frame-time check instead
//! ([`depthor_replay::synthetic::adversarial_frames`]); prints `frame <i> <name>` per frame.

use std::process::ExitCode;

fn run() -> Result<(), String> {
    let mut frames = 5u32;
    let mut adversarial = false;
    let mut out = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--frames" => {
                let v = args.next().ok_or("--frames needs a value")?;
                frames = v.parse().map_err(|e| format!("--frames {v}: {e}"))?;
            }
            "--adversarial" => adversarial = true,
            _ if out.is_none() => out = Some(a),
            _ => return Err(format!("unexpected argument {a}")),
        }
    }
    let out = out.ok_or("usage: make-image [--frames N | --adversarial] OUT")?;
    let cal = depthor_replay::synthetic::mcu_calibration();
    let data = if adversarial {
        let named = depthor_replay::synthetic::adversarial_frames();
        for (i, (name, _)) in named.iter().enumerate() {
            println!("frame {i} {name}");
        }
        named.into_iter().map(|(_, f)| f).collect()
    } else {
        depthor_replay::synthetic::mcu_frames(frames)
    };
    let file = std::fs::File::create(&out).map_err(|e| format!("{out}: {e}"))?;
    depthor_replay::writer::write_image(&cal, &data, std::io::BufWriter::new(file))
        .map_err(|e| format!("{out}: {e}"))?;
    Ok(())
}

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("make-image: {e}");
            ExitCode::FAILURE
        }
    }
}
