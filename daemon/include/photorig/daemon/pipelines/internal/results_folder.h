#pragma once
// A folder of solver results that readers, crashes and killed processes see
// whole or not at all. The solver writes into a hidden sibling
// (`.<name>.partial-<host>-<pid>`) and Commit() swaps it into place, so a
// batch task that is cancelled, pre-empted or re-queued mid-solve leaves the
// previous result (or none), never half of a new one.

#include <exception>
#include <stdexcept>
#include <string>

namespace photorig::daemon {

// Results that could not be written (a full disk, a read-only folder). The
// message names the destination, says that nothing was put there, and what to
// do before solving again.
struct ResultsWriteError : std::runtime_error {
  ResultsWriteError(const std::string& destination, const std::string& cause, bool disk_full);
  std::string destination;
  std::string cause;       // the failed operation, with the file and the system's reason
  bool disk_full = false;  // the filesystem holding the destination ran out of space
};

class ResultsFolder {
 public:
  // Creates the partial folder beside `destination`, first removing the
  // partial folders earlier, killed attempts left there. Throws
  // std::invalid_argument when `destination` exists and is not a results folder
  // (a file, or a folder holding files but no report.json): replacing it
  // would lose them.
  explicit ResultsFolder(const std::string& destination);
  // Removes the partial folder unless committed: an exception mid-solve leaves nothing.
  ~ResultsFolder();
  ResultsFolder(const ResultsFolder&) = delete;
  ResultsFolder& operator=(const ResultsFolder&) = delete;

  // Where the solver writes.
  const std::string& path() const { return partial_; }
  // Makes the folder durable and puts it at `destination` in one rename (an
  // exchange with the previous result, which is then removed).
  void Commit();
  // For a catch block around the writes: removes the partial folder (so its
  // files hold no space) and throws ResultsWriteError for `error` when it is a
  // file-system error (errno-carrying, or on a disk that is now full, or
  // another folder's ResultsWriteError); rethrows any other error unchanged.
  [[noreturn]] void Abandon(std::exception_ptr error);

 private:
  std::string destination_;
  std::string partial_;
  bool committed_ = false;
};

}  // namespace photorig::daemon
