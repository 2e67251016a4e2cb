#include "library_logging.h"

#include <glog/logging.h>
#include <opencv2/core/utils/logger.hpp>

namespace photorig::app {

void QuietLibraryLogging(const char* program) {
  // Before InitGoogleLogging: glog would otherwise write log files under /tmp.
  FLAGS_logtostderr = true;
  FLAGS_minloglevel = google::GLOG_FATAL;
  google::InitGoogleLogging(program);
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
}

}  // namespace photorig::app
