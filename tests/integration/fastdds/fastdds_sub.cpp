// fastdds-torque-sub: a Fast DDS 2.9 subscriber (another vendor, another process) for torque/EngineTorque,
// using fastddsgen's code for idl/torque.idl generated at build time. Loopback only: UDPv4 transport with
// 127.0.0.1 white-listed, unicast initial peer 127.0.0.1, no builtin multicast.
// Prints one line per sample "cycle kind fused_nm seq" and exits 0 after --count samples; exits 2 (loudly)
// if no writer matched or no sample arrived before the time-out (a type/topic-name mismatch is silent in
// DDS).
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>
#include <memory>
#include <string>
#include <thread>

#include "torquePubSubTypes.h"

using namespace eprosima::fastdds::dds;

int main(int argc, char** argv) {
  const int count = argc > 1 ? std::atoi(argv[1]) : 20;
  const double timeout_s = argc > 2 ? std::atof(argv[2]) : 30.0;
  const std::string topic_name = argc > 3 ? argv[3] : "torque/EngineTorque";

  DomainParticipantQos pq;
  pq.name("fastdds-torque-sub");
  pq.transport().use_builtin_transports = false;
  auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
  udp->interfaceWhiteList.emplace_back("127.0.0.1");
  pq.transport().user_transports.push_back(udp);
  pq.wire_protocol().builtin.avoid_builtin_multicast = true;
  eprosima::fastrtps::rtps::Locator_t peer;
  eprosima::fastrtps::rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
  pq.wire_protocol().builtin.initialPeersList.push_back(peer);
  pq.wire_protocol().builtin.discovery_config.leaseDuration_announcementperiod =
      eprosima::fastrtps::Duration_t(0, 200000000);

  DomainParticipant* p = DomainParticipantFactory::get_instance()->create_participant(0, pq);
  if (!p) {
    std::fprintf(stderr, "fastdds-torque-sub: cannot create participant\n");
    return 1;
  }
  TypeSupport type(new torque::EngineTorquePubSubType());
  type.register_type(p);
  Topic* topic = p->create_topic(topic_name, type.get_type_name(), TOPIC_QOS_DEFAULT);
  Subscriber* sub = p->create_subscriber(SUBSCRIBER_QOS_DEFAULT);
  DataReaderQos rq = DATAREADER_QOS_DEFAULT;
  rq.reliability().kind = RELIABLE_RELIABILITY_QOS;
  rq.history().kind = KEEP_LAST_HISTORY_QOS;
  rq.history().depth = 256;
  DataReader* reader = sub->create_datareader(topic, rq);
  std::fprintf(stderr, "fastdds-torque-sub: type %s topic %s\n", type.get_type_name().c_str(),
               topic_name.c_str());

  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  int got = 0;
  bool matched = false;
  while (got < count && std::chrono::steady_clock::now() < until) {
    SubscriptionMatchedStatus ms;
    reader->get_subscription_matched_status(ms);
    if (ms.current_count > 0 && !matched) {
      matched = true;
      std::fprintf(stderr, "fastdds-torque-sub: matched %d writer(s)\n", ms.current_count);
    }
    torque::EngineTorque s;
    SampleInfo info;
    while (got < count && reader->take_next_sample(&s, &info) == ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      std::printf("%u %u %.6f %llu %u\n", s.cycle(), static_cast<unsigned>(s.kind()), s.fused_nm(),
                  static_cast<unsigned long long>(s.seq()), static_cast<unsigned>(s.engine_id()));
      ++got;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  std::fflush(stdout);
  p->delete_contained_entities();
  DomainParticipantFactory::get_instance()->delete_participant(p);
  if (!matched) {
    std::fprintf(
        stderr, "fastdds-torque-sub: FAILED: no Cyclone writer matched '%s' (type or topic name mismatch?)\n",
        topic_name.c_str());
    return 2;
  }
  if (got < count) {
    std::fprintf(stderr, "fastdds-torque-sub: FAILED: matched but only %d of %d samples arrived\n", got,
                 count);
    return 2;
  }
  std::fprintf(stderr, "fastdds-torque-sub: %d samples\n", got);
  return 0;
}
