//! Admission limits on stored data and per-tenant queues.
//!
//! Stored bytes are the uploads (`input_bytes`) plus the listed artifacts of
//! every job record, summed by the store at admission time, so the figure is
//! exact across restarts, crashes, deletes and expiry without bookkeeping in
//! the runner. The files of a job still running count from the moment it
//! finishes (its artifacts are listed then). Checks run under the service's
//! admission lock together with the insert, so two concurrent uploads cannot
//! both take the last free bytes.

use super::service::JobsError;
use super::store::JobStore;

/// Limits applied when a job is submitted (all off by default).
#[derive(Debug, Clone, Default)]
pub struct Quotas {
    /// Most bytes of uploads and artifacts stored in all (507 beyond).
    pub max_stored_bytes: Option<u64>,
    /// Most queued jobs of one tenant (429 beyond).
    pub tenant_max_queued: Option<usize>,
    /// Most bytes of uploads and artifacts stored by one tenant (507 beyond).
    pub tenant_max_stored_bytes: Option<u64>,
}

/// Refuses a job of `incoming` bytes from `tenant` (`None`: no
/// authentication) when it would exceed a limit of `quotas`.
///
/// # Errors
/// [`JobsError::TenantQueueFull`], [`JobsError::QuotaExceeded`], or
/// [`JobsError::Store`] on database failure.
pub(crate) fn check_admission(
    store: &dyn JobStore,
    quotas: &Quotas,
    tenant: Option<&str>,
    incoming: u64,
) -> Result<(), JobsError> {
    if let Some(max) = quotas.max_stored_bytes
        && store.stored_bytes(None)?.saturating_add(incoming) > max
    {
        return Err(JobsError::QuotaExceeded { tenant: false, max_bytes: max });
    }
    let Some(tenant) = tenant else { return Ok(()) };
    if let Some(max) = quotas.tenant_max_queued
        && store.queued_count_of(tenant)? >= max
    {
        return Err(JobsError::TenantQueueFull { max_queued: max });
    }
    if let Some(max) = quotas.tenant_max_stored_bytes
        && store.stored_bytes(Some(tenant))?.saturating_add(incoming) > max
    {
        return Err(JobsError::QuotaExceeded { tenant: true, max_bytes: max });
    }
    Ok(())
}
