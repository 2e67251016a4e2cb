#pragma once
// What the libraries under photorig print on their own: Ceres logs through
// glog (uninitialised, it prefixes "Logging before InitGoogleLogging" to
// each line, and the covariance of a rank-deficient fit is an ERROR there),
// OpenCV warns on stderr about files it cannot read. photorig reports both
// itself (a fit's covariance_available, an unreadable file named with what
// to do), so the executables keep the libraries to their fatal errors.

namespace photorig::app {

void QuietLibraryLogging(const char* program);

}  // namespace photorig::app
