// tests/publish/test_status.cpp: DaemonStatus a controller can trust (publish/status.hpp): drops and overruns
// are separate flags that say "since the previous status" and clear when the condition has gone, while the
// counters keep the history; a failed recording degrades health; health OK again once everything is clean.
#include <gtest/gtest.h>

#include "status.hpp"

namespace torqued {
namespace {

RuntimeCounters synced() {
  RuntimeCounters c;
  c.synced = true;
  return c;
}

TEST(DaemonStatus, OverrunIsItsOwnFlagAndClearsWhenGone) {
  StatusTracker st;
  RuntimeCounters c = synced();
  EXPECT_EQ(st.next(c, 0, 0).u.status.health, torque_DAEMON_OK);
  c.overruns = 1;  // one late 1 kHz tick: nothing was dropped
  const auto a = st.next(c, 1, 1).u.status;
  EXPECT_NE(a.flags & torque_STATUS_OVERRUNS, 0u);
  EXPECT_EQ(a.flags & torque_STATUS_DROPS, 0u);
  EXPECT_EQ(a.health, torque_DAEMON_DEGRADED);
  const auto b = st.next(c, 2, 2).u.status;  // no new overrun since
  EXPECT_EQ(b.flags & torque_STATUS_OVERRUNS, 0u);
  EXPECT_EQ(b.overruns, 1u) << "the counter keeps the history";
  EXPECT_EQ(b.health, torque_DAEMON_OK);
}

TEST(DaemonStatus, DropsOfAnyKindSetDropsForOnePeriod) {
  StatusTracker st;
  RuntimeCounters c = synced();
  (void)st.next(c, 0, 0);
  for (std::uint64_t RuntimeCounters::*field :
       {&RuntimeCounters::ring_drops_edge, &RuntimeCounters::ring_drops_can, &RuntimeCounters::ring_drops_out,
        &RuntimeCounters::source_drops}) {
    c.*field += 3;
    const auto a = st.next(c, 0, 0).u.status;
    EXPECT_NE(a.flags & torque_STATUS_DROPS, 0u);
    EXPECT_EQ(a.health, torque_DAEMON_DEGRADED);
    EXPECT_EQ(st.next(c, 0, 0).u.status.flags & torque_STATUS_DROPS, 0u);
  }
}

TEST(DaemonStatus, RecordErrorAndNoSyncDegradeSeqCounts) {
  StatusTracker st;
  RuntimeCounters c = synced();
  c.flags = torque_STATUS_RECORD_ERROR;
  const auto a = st.next(c, 5, 7).u.status;
  EXPECT_EQ(a.health, torque_DAEMON_DEGRADED);
  EXPECT_EQ(a.seq, 1u);
  EXPECT_EQ(a.source_t_ns, 5);
  EXPECT_EQ(a.uptime_ns, 7);
  RuntimeCounters n;  // not synced, no edges: failed
  n.flags = torque_STATUS_EDGE_TIMEOUT;
  const auto b = st.next(n, 0, 0).u.status;
  EXPECT_EQ(b.seq, 2u);
  EXPECT_EQ(b.health, torque_DAEMON_FAILED);
  EXPECT_NE(b.validity & torque_VALIDITY_NO_SYNC, 0u);
}

TEST(DaemonStatus, ReplayDoneIsNotAFaultButOwnConditionsStillCount) {
  // GIVEN a replay that consumed its recording: no sync, no edges, CAN stale. THEN health ok (the flags still
  // say why), where the same counters without REPLAY_DONE say failed; an overrun of its own still degrades.
  StatusTracker st;
  RuntimeCounters n;
  n.flags = torque_STATUS_EDGE_TIMEOUT | torque_STATUS_REPLAY_DONE;
  n.sensor_timeouts = 1u;
  const auto a = st.next(n, 0, 0).u.status;
  EXPECT_EQ(a.health, torque_DAEMON_OK);
  EXPECT_NE(a.flags & torque_STATUS_NO_SYNC, 0u);
  EXPECT_NE(a.flags & torque_STATUS_CAN_TIMEOUT, 0u);
  n.overruns = 1;
  EXPECT_EQ(st.next(n, 0, 0).u.status.health, torque_DAEMON_DEGRADED);
  n.flags = torque_STATUS_EDGE_TIMEOUT;
  EXPECT_EQ(st.next(n, 0, 0).u.status.health, torque_DAEMON_FAILED);
}

}  // namespace
}  // namespace torqued
