// The coordinator's disk refused a write (ENOSPC, EDQUOT, SQLITE_FULL). It is the operator's
// problem, not a job's: the coordinator pauses the work that writes (new jobs, leases, planning)
// and resumes when space returns, instead of failing jobs or crashing.
#pragma once

#include <cerrno>
#include <stdexcept>
#include <string>

namespace lightfarm {

class StorageFull : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// True for the errno values that mean "no space": the failed write was not the data's fault.
inline bool IsNoSpaceErrno(int err) { return err == ENOSPC || err == EDQUOT; }

}  // namespace lightfarm
