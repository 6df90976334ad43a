#include "coordinator/farm_metrics.h"

#include <sstream>

namespace lightfarm {

std::string PrometheusText(const FarmCounters& c, const FarmGauges& g) {
  std::ostringstream os;
  os << "# HELP lightfarm_jobs Jobs by state.\n# TYPE lightfarm_jobs gauge\n";
  for (const char* s : {"queued", "planning", "running", "done", "failed", "cancelled"}) {
    const auto it = g.jobs_by_state.find(s);
    os << "lightfarm_jobs{state=\"" << s << "\"} " << (it == g.jobs_by_state.end() ? 0 : it->second) << "\n";
  }
  auto counter = [&](const char* name, const char* help, uint64_t v) {
    os << "# HELP " << name << " " << help << "\n# TYPE " << name << " counter\n" << name << " " << v << "\n";
  };
  auto gauge = [&](const char* name, const char* help, uint64_t v) {
    os << "# HELP " << name << " " << help << "\n# TYPE " << name << " gauge\n" << name << " " << v << "\n";
  };
  gauge("lightfarm_tasks_pending", "Tasks of running jobs waiting for a worker.", g.tasks_pending);
  gauge("lightfarm_tasks_leased", "Tasks leased to workers.", g.tasks_leased);
  gauge("lightfarm_workers_registered", "Workers registered since the state directory was created.", g.workers);
  counter("lightfarm_jobs_submitted_total", "Jobs accepted.", c.submitted);
  counter("lightfarm_leases_total", "Task leases granted.", c.leases);
  counter("lightfarm_lease_polls_total", "LeaseTask calls.", c.lease_polls);
  counter("lightfarm_tasks_completed_total", "Task results accepted.", c.completed);
  counter("lightfarm_tasks_duplicate_total", "Duplicate or stale task results ignored.", c.duplicates);
  counter("lightfarm_task_failures_total", "Failed task attempts (including expired leases).", c.failed);
  counter("lightfarm_leases_expired_total", "Leases that expired without a heartbeat.", c.expired);
  gauge("lightfarm_storage_full", "1 while the state directory is too full to take new work.", g.storage_full ? 1 : 0);
  counter("lightfarm_storage_full_total", "Times the state directory filled up (writes refused or space below --min-free-mb).",
          c.storage_full);
  counter("lightfarm_tasks_verified_total", "Tasks whose result two workers agreed on bit for bit.", c.verified);
  counter("lightfarm_verification_mismatches_total", "Verified tasks whose first two results differed.", c.mismatches);
  counter("lightfarm_job_repairs_total", "Times a corrupted blob or a blocklisted worker sent a job back to recompute.",
          c.repairs);
  counter("lightfarm_scrub_bytes_total", "Bytes of stored blobs re-hashed by the scrub.", c.scrubbed_bytes);
  counter("lightfarm_scrub_passes_total", "Complete passes of the scrub over the blob store.", c.scrub_passes);
  counter("lightfarm_gc_blobs_removed_total", "Blobs no job referenced, removed by the collection.", c.gc_removed);
  counter("lightfarm_gc_bytes_removed_total", "Bytes of those blobs.", c.gc_removed_bytes);
  counter("lightfarm_jobs_deleted_total", "Jobs deleted (by request or the retention policy).", c.deleted);
  counter("lightfarm_blobs_corrupted_total", "Blobs found corrupted on the coordinator's disk and quarantined.",
          g.blobs_corrupted);
  return os.str();
}

}  // namespace lightfarm
