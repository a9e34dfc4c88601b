//! What the report says about the machine and the software it ran on.

use std::process::Command;

/// Machine and versions, for the report's header.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineInfo {
    /// CPU model (`/proc/cpuinfo` "model name"), or "unknown".
    pub cpu: String,
    /// Logical cores available to this process.
    pub cores: usize,
    /// Operating system (`/etc/os-release` PRETTY_NAME and the kernel release).
    pub os: String,
    /// `rustc --version` of the toolchain on PATH (the one `cargo` builds with), or "unknown".
    pub rustc: String,
    /// hyrt's crate version, plus the git commit when run from a checkout.
    pub hyrt: String,
    /// Load averages over 1, 5 and 15 minutes when the run started (`/proc/loadavg`):
    /// other work on a shared machine slows every measurement.
    pub load: String,
}

fn read(path: &str) -> Option<String> {
    std::fs::read_to_string(path).ok()
}

fn command(cmd: &str, args: &[&str]) -> Option<String> {
    let out = Command::new(cmd).args(args).current_dir(env!("CARGO_MANIFEST_DIR")).output().ok()?;
    out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
}

impl MachineInfo {
    /// Gather what can be found; missing pieces read "unknown".
    pub fn detect() -> MachineInfo {
        let cpu = read("/proc/cpuinfo")
            .and_then(|s| {
                s.lines()
                    .find(|l| l.starts_with("model name"))
                    .and_then(|l| l.split_once(':'))
                    .map(|(_, v)| v.trim().to_string())
            })
            .unwrap_or_else(|| "unknown".into());
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let pretty = read("/etc/os-release").and_then(|s| {
            s.lines().find_map(|l| l.strip_prefix("PRETTY_NAME=")).map(|v| v.trim_matches('"').to_string())
        });
        let kernel = read("/proc/sys/kernel/osrelease").map(|s| s.trim().to_string());
        let os = match (pretty, kernel) {
            (Some(p), Some(k)) => format!("{p}, Linux {k}"),
            (Some(p), None) => p,
            (None, Some(k)) => format!("Linux {k}"),
            (None, None) => std::env::consts::OS.to_string(),
        };
        let rustc = command("rustc", &["--version"]).unwrap_or_else(|| "unknown".into());
        let mut hyrt = env!("CARGO_PKG_VERSION").to_string();
        if let Some(commit) = command("git", &["rev-parse", "--short", "HEAD"]) {
            let dirty =
                command("git", &["status", "--porcelain", "--untracked-files=no"]).is_some_and(|s| !s.is_empty());
            hyrt = format!("{hyrt} (git {commit}{})", if dirty { ", modified" } else { "" });
        }
        let load = load_average().map_or_else(|| "unknown".into(), |l| format!("{:.2} {:.2} {:.2}", l[0], l[1], l[2]));
        MachineInfo { cpu, cores, os, rustc, hyrt, load }
    }
}

/// Load averages over 1, 5 and 15 minutes (`/proc/loadavg`), if readable.
pub fn load_average() -> Option<[f64; 3]> {
    let s = read("/proc/loadavg")?;
    let v: Vec<f64> = s.split_whitespace().take(3).filter_map(|x| x.parse().ok()).collect();
    v.try_into().ok()
}

/// A warning when the machine was busy with other work (1-minute load average above
/// the core count): times are then inflated and thread scaling says little.
pub fn busy_warning(cores: usize) -> Option<String> {
    let l = load_average()?;
    (l[0] > cores as f64).then(|| {
        format!(
            "**The machine was busy**: 1-minute load average {:.2} on {cores} cores, so other work shared the \
             cores; times are inflated and the 1- and 2-thread figures say little about thread scaling. \
             Ratios within one table (same rays, measured back to back) are more robust than absolute times.",
            l[0]
        )
    })
}
