//! The name a process holds leases under, `HOST/PID/NONCE`, and the test
//! that lets a restarted process take back at once the jobs a dead process
//! of the same machine held, instead of waiting for their leases to expire.
//!
//! A name is judged dead only when its host is this host and either its
//! PID is this process's with another nonce (a previous run of the same PID,
//! as a container's PID 1 is on every start) or no process has that PID.
//! Anything else (another host, a live PID that may be reused) waits for
//! the lease to expire, and the fencing of every write keeps even a wrong
//! judgement from letting two attempts both finish.

use std::sync::Arc;

/// This process's lease owner name.
#[derive(Debug, Clone)]
pub struct WorkerName {
    full: Arc<str>,
    host: String,
    pid: u32,
    nonce: String,
}

/// The machine's host name (`/proc/sys/kernel/hostname`, else `$HOSTNAME`,
/// else `unknown-host`), with `/` replaced so it cannot split the name.
fn host_name() -> String {
    let h = std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok().filter(|s| !s.is_empty()))
        .unwrap_or_else(|| "unknown-host".into());
    h.replace('/', "_")
}

impl WorkerName {
    /// The name of this process: host, PID and a random nonce.
    pub fn of_this_process() -> Self {
        let host = host_name();
        let pid = std::process::id();
        let nonce = uuid::Uuid::new_v4().simple().to_string()[..12].to_string();
        Self { full: format!("{host}/{pid}/{nonce}").into(), host, pid, nonce }
    }

    /// The name as stored in `lease_owner`.
    pub fn as_str(&self) -> &str {
        &self.full
    }

    /// The name, shared.
    pub fn shared(&self) -> Arc<str> {
        self.full.clone()
    }

    /// Whether the process named `other` is certainly gone (see the module
    /// doc); `false` when unsure.
    pub fn is_dead(&self, other: &str) -> bool {
        let mut parts = other.splitn(3, '/');
        let (Some(host), Some(pid), Some(nonce)) = (parts.next(), parts.next(), parts.next()) else {
            return false;
        };
        let Ok(pid) = pid.parse::<u32>() else { return false };
        if host != self.host {
            return false;
        }
        if pid == self.pid {
            return nonce != self.nonce;
        }
        cfg!(target_os = "linux") && !std::path::Path::new(&format!("/proc/{pid}")).exists()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_processes_of_this_host_that_are_gone_are_dead() {
        let me = WorkerName::of_this_process();
        assert!(!me.is_dead(me.as_str()), "this process is alive");
        let host = &me.host;
        assert!(me.is_dead(&format!("{host}/{}/0123456789ab", me.pid)), "same PID, other nonce: an earlier run");
        // The parent (cargo or nextest) is alive; PID 4194304 is above Linux's pid_max.
        let parent = std::os::unix::process::parent_id();
        assert!(!me.is_dead(&format!("{host}/{parent}/x")));
        assert!(me.is_dead(&format!("{host}/4194304/x")));
        assert!(!me.is_dead("another-host/4194304/x"), "another host: wait for the lease");
        assert!(!me.is_dead("garbage"));
    }
}
