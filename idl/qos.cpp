#include "qos.hpp"

namespace torqued::dds {

dds_qos_t* make_qos(const TopicQos& q) {
  dds_qos_t* qos = dds_create_qos();
  if (q.reliable) {
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  } else {
    dds_qset_reliability(qos, DDS_RELIABILITY_BEST_EFFORT, 0);
  }
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, q.depth);
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  dds_qset_deadline(qos, q.deadline_ms > 0 ? DDS_MSECS(q.deadline_ms) : DDS_INFINITY);
  dds_qset_liveliness(qos, DDS_LIVELINESS_AUTOMATIC, q.lease_ms > 0 ? DDS_MSECS(q.lease_ms) : DDS_INFINITY);
  // Fast DDS 2.9 and ROS 2 peers speak XCDR1 only; @final types and XCDR1 keep the wire format compatible.
  dds_data_representation_id_t rep = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &rep);
  return qos;
}

dds_entity_t create_topic(dds_entity_t participant, const DdsSettings& s, Topic t) {
  const dds_topic_descriptor_t* desc = nullptr;
  switch (t) {
    case Topic::kEngineTorque:
      desc = TopicTraits<torque_EngineTorque>::descriptor();
      break;
    case Topic::kEstimatorTorque:
      desc = TopicTraits<torque_EstimatorTorque>::descriptor();
      break;
    case Topic::kCylinderTorque:
      desc = TopicTraits<torque_CylinderTorque>::descriptor();
      break;
    case Topic::kCrankState:
      desc = TopicTraits<torque_CrankState>::descriptor();
      break;
    case Topic::kDaemonStatus:
      desc = TopicTraits<torque_DaemonStatus>::descriptor();
      break;
  }
  const std::string name = s.topic_name(t);
  return dds_create_topic(participant, desc, name.c_str(), nullptr, nullptr);
}

}  // namespace torqued::dds
