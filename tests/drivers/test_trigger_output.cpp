// TriggerOutput as a checked state machine: the public methods refuse
// illegal transitions without calling the implementation, and Close leaves
// the output deasserted from any state.

#include "photorig/drivers/internal/safety_net.h"
#include "photorig/drivers/trigger_output.h"

#include <gtest/gtest.h>

namespace photorig::drivers {
namespace {

using std::chrono::microseconds;

// Which hooks ran and the output's level; outlives the output it records.
struct Record {
  int opens = 0, fires = 0, closes = 0;
  bool asserted = false;
};

class RecordingOutput : public TriggerOutput {
 public:
  explicit RecordingOutput(Record* record) : TriggerOutput("rec"), r_(*record) {}
  ~RecordingOutput() override { (void)Close(); }

  Status open_result = Status::Ok();
  Status close_result = Status::Ok();
  bool fail_deassert = false;  // a pulse that cannot be ended: the output is left asserted

 protected:
  Status DoOpen() override {
    ++r_.opens;
    return open_result;
  }
  Status DoFire(microseconds) override {
    ++r_.fires;
    r_.asserted = true;
    if (fail_deassert) return {StatusCode::kUnavailable, "deassert failed"};
    r_.asserted = false;
    return Status::Ok();
  }
  Status DoClose() override {
    ++r_.closes;
    r_.asserted = false;
    return close_result;
  }

 private:
  Record& r_;
};

TEST(TriggerOutput, IllegalTransitionsAreRefusedWithoutReachingTheDevice) {
  Record record;
  RecordingOutput output(&record);
  const Status closed_fire = output.Fire(microseconds(100));
  EXPECT_EQ(closed_fire.code(), StatusCode::kFailedPrecondition);
  EXPECT_NE(closed_fire.message().find("trigger rec: cannot fire while closed"), std::string::npos)
      << closed_fire.message();
  EXPECT_EQ(record.fires, 0);
  EXPECT_EQ(output.state(), TriggerOutput::State::kClosed);

  ASSERT_TRUE(output.Open().ok());
  EXPECT_EQ(output.state(), TriggerOutput::State::kOpen);
  EXPECT_EQ(output.Open().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(record.opens, 1);
  EXPECT_EQ(output.state(), TriggerOutput::State::kOpen);

  EXPECT_EQ(output.Fire(microseconds(0)).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(output.Fire(microseconds(-5)).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(record.fires, 0);
  ASSERT_TRUE(output.Fire(microseconds(100)).ok());
  ASSERT_TRUE(output.Fire(microseconds(100)).ok());
  EXPECT_EQ(record.fires, 2);
  EXPECT_EQ(output.state(), TriggerOutput::State::kOpen);

  ASSERT_TRUE(output.Close().ok());
  EXPECT_EQ(output.state(), TriggerOutput::State::kClosed);
  ASSERT_TRUE(output.Close().ok());  // twice is harmless and does not touch the device
  EXPECT_EQ(record.closes, 1);
  EXPECT_EQ(output.Fire(microseconds(100)).code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(record.fires, 2);

  ASSERT_TRUE(output.Open().ok());  // reopening after close is legal
  EXPECT_EQ(record.opens, 2);
}

TEST(TriggerOutput, AFailedOpenLeavesItClosed) {
  Record record;
  RecordingOutput output(&record);
  output.open_result = {StatusCode::kUnavailable, "no such line"};
  EXPECT_EQ(output.Open().code(), StatusCode::kUnavailable);
  EXPECT_EQ(output.state(), TriggerOutput::State::kClosed);
  EXPECT_EQ(output.Fire(microseconds(100)).code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(SafetyNet::size(), 0);
  ASSERT_TRUE(output.Close().ok());
  EXPECT_EQ(record.closes, 0);
}

TEST(TriggerOutput, CloseAfterAPulseThatStuckDeassertsAndReportsAFailedRelease) {
  Record record;
  RecordingOutput output(&record);
  ASSERT_TRUE(output.Open().ok());
  output.fail_deassert = true;
  EXPECT_EQ(output.Fire(microseconds(100)).code(), StatusCode::kUnavailable);
  EXPECT_TRUE(record.asserted);
  EXPECT_EQ(output.state(), TriggerOutput::State::kOpen);
  ASSERT_TRUE(output.Close().ok());
  EXPECT_FALSE(record.asserted);

  // A release that fails still ends in Closed: nothing is left to fire.
  ASSERT_TRUE(output.Open().ok());
  output.close_result = {StatusCode::kInternal, "release failed"};
  EXPECT_EQ(output.Close().code(), StatusCode::kInternal);
  EXPECT_EQ(output.state(), TriggerOutput::State::kClosed);
  EXPECT_EQ(SafetyNet::size(), 0);
}

TEST(TriggerOutput, AnOpenOutputIsInTheSafetyNetUntilClosed) {
  Record record;
  RecordingOutput output(&record);
  ASSERT_TRUE(output.Open().ok());
  EXPECT_EQ(SafetyNet::size(), 1);
  ASSERT_TRUE(output.Close().ok());
  EXPECT_EQ(SafetyNet::size(), 0);

  ASSERT_TRUE(output.Open().ok());
  output.fail_deassert = true;
  (void)output.Fire(microseconds(100));
  SafetyNet::ShutdownAll();
  EXPECT_EQ(output.state(), TriggerOutput::State::kClosed);
  EXPECT_FALSE(record.asserted);
  EXPECT_EQ(SafetyNet::size(), 0);
}

TEST(TriggerOutput, DestroyingAnOpenOutputClosesIt) {
  Record record;
  {
    RecordingOutput output(&record);
    ASSERT_TRUE(output.Open().ok());
    output.fail_deassert = true;
    (void)output.Fire(microseconds(100));
    ASSERT_TRUE(record.asserted);
  }
  EXPECT_FALSE(record.asserted);
  EXPECT_EQ(record.closes, 1);
  EXPECT_EQ(SafetyNet::size(), 0);
}

}  // namespace
}  // namespace photorig::drivers
