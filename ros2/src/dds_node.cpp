// SPDX-License-Identifier: BSD-3-Clause
#include "dds_node.hpp"

#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

namespace fnmpc::ros2 {

std::string TypeHashUserData(const std::string& type_hash) { return "typehash=" + type_hash + ";"; }

std::uint32_t DomainIdFromEnvironment() {
  const char* value = std::getenv("ROS_DOMAIN_ID");
  if (value == nullptr || *value == '\0') return 0;
  char* end = nullptr;
  const long id = std::strtol(value, &end, 10);
  // 232: the largest domain whose RTPS ports fit in 16 bits (ROS 2's documented range).
  if (*end != '\0' || id < 0 || id > 232) {
    throw std::invalid_argument(
        fmt::format("ROS_DOMAIN_ID '{}': not an integer in [0, 232]", value));
  }
  return static_cast<std::uint32_t>(id);
}

dds_return_t CheckDds(dds_return_t rc, const std::string& what) {
  if (rc < 0) throw std::runtime_error(fmt::format("DDS: {}: {}", what, dds_strretcode(rc)));
  return rc;
}

Participant::Participant(std::uint32_t domain_id) {
  participant_ = dds_create_participant(domain_id, nullptr, nullptr);
  CheckDds(participant_,
           fmt::format("participant in domain {} (CYCLONEDDS_URI: {})", domain_id,
                       std::getenv("CYCLONEDDS_URI") ? std::getenv("CYCLONEDDS_URI") : "unset"));
}

Participant::~Participant() { dds_delete(participant_); }

dds_qos_t* MakeEndpointQos(const QosProfile& profile, const char* type_hash) {
  dds_qos_t* qos = dds_create_qos();
  if (profile.reliable) {
    dds_qset_reliability(qos, DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  } else {
    dds_qset_reliability(qos, DDS_RELIABILITY_BEST_EFFORT, 0);
  }
  dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, profile.depth);
  dds_qset_durability(qos, DDS_DURABILITY_VOLATILE);
  const dds_data_representation_id_t xcdr1 = DDS_DATA_REPRESENTATION_XCDR1;
  dds_qset_data_representation(qos, 1, &xcdr1);
  const std::string user_data = TypeHashUserData(type_hash);
  dds_qset_userdata(qos, user_data.data(), user_data.size());
  return qos;
}

namespace detail {
dds_entity_t CreateTopic(const Participant& participant, const dds_topic_descriptor_t* descriptor,
                         const std::string& dds_topic, const QosProfile& profile,
                         const char* type_hash) {
  dds_qos_t* qos = MakeEndpointQos(profile, type_hash);
  const dds_entity_t topic =
      dds_create_topic(participant.handle(), descriptor, dds_topic.c_str(), qos, nullptr);
  dds_delete_qos(qos);
  return CheckDds(topic, fmt::format("topic {} of type {}", dds_topic, descriptor->m_typename));
}
}  // namespace detail

builtin_interfaces_msg_dds__Time_ ToRosTime(double seconds) {
  builtin_interfaces_msg_dds__Time_ t{};
  const double whole = std::floor(seconds);
  t.sec = static_cast<std::int32_t>(whole);
  auto nanosec = static_cast<std::int64_t>(std::llround((seconds - whole) * 1e9));
  if (nanosec >= 1000000000) {
    t.sec += 1;
    nanosec -= 1000000000;
  }
  t.nanosec = static_cast<std::uint32_t>(nanosec);
  return t;
}

double FromRosTime(const builtin_interfaces_msg_dds__Time_& t) { return t.sec + t.nanosec * 1e-9; }

}  // namespace fnmpc::ros2
