#include "dds_publisher.hpp"

#include <time.h>

#include <cstring>

#include "dds/ddsc/dds_loan_api.h"

namespace torqued {

std::int64_t DdsPublisher::realtime_ns() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

DdsPublisher::DdsPublisher(const dds::DdsSettings& settings, bool stamp_times)
    : settings_(settings), stamp_times_(stamp_times) {
  participant_ = dds_create_participant(settings_.domain_id, nullptr, nullptr);
  if (participant_ < 0) {
    error_ = std::string("dds_create_participant: ") + dds_strretcode(participant_);
    return;
  }
  for (int i = 0; i < dds::kTopicCount; ++i) {
    const auto t = static_cast<dds::Topic>(i);
    const dds_entity_t topic = dds::create_topic(participant_, settings_, t);
    if (topic < 0) {
      error_ = "dds_create_topic '" + settings_.topic_name(t) + "': " + dds_strretcode(topic);
      return;
    }
    dds_qos_t* qos = dds::make_qos(settings_.qos[static_cast<std::size_t>(i)]);
    writers_[static_cast<std::size_t>(i)] = dds_create_writer(participant_, topic, qos, nullptr);
    dds_delete_qos(qos);
    if (writers_[static_cast<std::size_t>(i)] < 0) {
      error_ = "dds_create_writer '" + settings_.topic_name(t) +
               "': " + dds_strretcode(writers_[static_cast<std::size_t>(i)]);
      return;
    }
    shm_[static_cast<std::size_t>(i)] = dds_is_shared_memory_available(writers_[static_cast<std::size_t>(i)]);
    loan_[static_cast<std::size_t>(i)] = dds_is_loan_available(writers_[static_cast<std::size_t>(i)]);
  }
}

std::string DdsPublisher::shared_memory_topics() const {
  std::string r;
  for (int i = 0; i < dds::kTopicCount; ++i)
    if (shm_[static_cast<std::size_t>(i)]) {
      if (!r.empty()) r += ' ';
      r += dds::kTopicNames[i];
      if (!loan_[static_cast<std::size_t>(i)]) r += "(no loans)";
    }
  return r;
}

DdsPublisher::~DdsPublisher() {
  if (participant_ > 0) dds_delete(participant_);
}

bool DdsPublisher::write(dds::AnySample& s) noexcept {
  const dds_entity_t w = writers_[static_cast<std::size_t>(s.topic)];
  if (w <= 0) {
    ++write_errors_;
    return false;
  }
  const std::int64_t now = stamp_times_ ? realtime_ns() : 0;
  const std::uint16_t engine = settings_.engine_id;
  const bool loan = loan_[static_cast<std::size_t>(s.topic)];
  const dds_return_t rc = s.visit([&](auto& v) {
    v.engine_id = engine;
    v.publish_t_ns = now;
    // Shared memory: fill a sample lent by iceoryx (fixed-size type: one copy, no serialisation) and hand it
    // back with dds_write, which publishes it to same-host readers and serialises it only for remote ones.
    void* lent = nullptr;
    if (loan && dds_loan_sample(w, &lent) == DDS_RETCODE_OK && lent) {
      std::memcpy(lent, &v, sizeof v);
      ++loaned_;
      return dds_write(w, lent);
    }
    return dds_write(w, &v);
  });
  if (rc != DDS_RETCODE_OK) {
    ++write_errors_;
    return false;
  }
  ++written_;
  return true;
}

int DdsPublisher::matched_readers(dds::Topic t) const noexcept {
  dds_publication_matched_status_t st{};
  if (dds_get_publication_matched_status(writers_[static_cast<std::size_t>(t)], &st) != DDS_RETCODE_OK)
    return -1;
  return static_cast<int>(st.current_count);
}

}  // namespace torqued
