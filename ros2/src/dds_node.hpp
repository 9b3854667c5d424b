// SPDX-License-Identifier: BSD-3-Clause
// Cyclone DDS entities under the ROS 2 conventions (docs/ros2.md): what a ROS 2 node on
// rmw_cyclonedds_cpp or rmw_fastrtps_cpp sees as its own. Topic "rt/<name>", type
// "<pkg>::msg::dds_::<Name>_" (Ros2Type<>), XCDR1 data representation, the ROS 2 QoS profiles
// set explicitly, USER_DATA "typehash=RIHS01_...;" (REP 2011) on every reader and writer.
#pragma once

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>

#include <dds/dds.h>

#include "fnmpc_ros2/msg_types.hpp"

namespace fnmpc::ros2 {

// The two ROS 2 QoS profiles used here: rmw_qos_profile_default (RELIABLE, KEEP_LAST 10,
// VOLATILE) and rmw_qos_profile_sensor_data (BEST_EFFORT, KEEP_LAST 5, VOLATILE).
struct QosProfile {
  bool reliable = true;
  int depth = 10;
  static QosProfile Default() { return {true, 10}; }
  static QosProfile SensorData() { return {false, 5}; }
};

// USER_DATA of a ROS 2 (Iron and later) endpoint: "typehash=<RIHS01 hash>;".
std::string TypeHashUserData(const std::string& type_hash);

// ROS_DOMAIN_ID from the environment (0 when unset); throws std::invalid_argument naming the
// value when it is not an integer in [0, 232].
std::uint32_t DomainIdFromEnvironment();

// One DDS domain participant (a ROS 2 context). Cyclone reads CYCLONEDDS_URI for its
// configuration (ros2/config/cyclonedds-loopback.xml for loopback).
class Participant {
 public:
  explicit Participant(std::uint32_t domain_id = DomainIdFromEnvironment());
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;
  dds_entity_t handle() const { return participant_; }

 private:
  dds_entity_t participant_;
};

// A QoS object for a ROS 2 endpoint of the given profile and type hash (owned by the caller,
// dds_delete_qos).
dds_qos_t* MakeEndpointQos(const QosProfile& profile, const char* type_hash);

// Throws std::runtime_error naming `what` and Cyclone's message when `rc` is an error.
dds_return_t CheckDds(dds_return_t rc, const std::string& what);

// ROS time <-> seconds.
builtin_interfaces_msg_dds__Time_ ToRosTime(double seconds);
double FromRosTime(const builtin_interfaces_msg_dds__Time_& t);

namespace detail {
dds_entity_t CreateTopic(const Participant& participant, const dds_topic_descriptor_t* descriptor,
                         const std::string& dds_topic, const QosProfile& profile,
                         const char* type_hash);
}

template <typename Message>
class Writer {
 public:
  Writer(const Participant& participant, const std::string& dds_topic, const QosProfile& profile)
      : topic_name_(dds_topic) {
    using T = Ros2Type<Message>;
    const dds_entity_t topic =
        detail::CreateTopic(participant, T::Descriptor(), dds_topic, profile, T::kTypeHash);
    dds_qos_t* qos = MakeEndpointQos(profile, T::kTypeHash);
    writer_ = dds_create_writer(participant.handle(), topic, qos, nullptr);
    dds_delete_qos(qos);
    CheckDds(writer_, "writer on " + dds_topic);
  }
  ~Writer() { dds_delete(writer_); }
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;
  void Write(const Message& message) {
    CheckDds(dds_write(writer_, &message), "write to " + topic_name_);
  }
  // Matched readers (subscriptions) now.
  std::uint32_t Subscriptions() const {
    dds_publication_matched_status_t status{};
    CheckDds(dds_get_publication_matched_status(writer_, &status),
             "matched status of " + topic_name_);
    return status.current_count;
  }
  dds_entity_t handle() const { return writer_; }

 private:
  std::string topic_name_;
  dds_entity_t writer_;
};

template <typename Message>
class Reader {
 public:
  Reader(const Participant& participant, const std::string& dds_topic, const QosProfile& profile)
      : topic_name_(dds_topic) {
    using T = Ros2Type<Message>;
    const dds_entity_t topic =
        detail::CreateTopic(participant, T::Descriptor(), dds_topic, profile, T::kTypeHash);
    dds_qos_t* qos = MakeEndpointQos(profile, T::kTypeHash);
    reader_ = dds_create_reader(participant.handle(), topic, qos, nullptr);
    dds_delete_qos(qos);
    CheckDds(reader_, "reader on " + dds_topic);
  }
  ~Reader() { dds_delete(reader_); }
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;
  // Takes every sample received so far, oldest first; returns how many had data.
  int TakeAll(const std::function<void(const Message&)>& handle) {
    int count = 0;
    for (;;) {
      void* samples[1] = {nullptr};
      dds_sample_info_t info[1];
      const dds_return_t n = dds_take(reader_, samples, info, 1, 1);
      CheckDds(n, "take from " + topic_name_);
      if (n == 0) return count;
      if (info[0].valid_data) {
        ++count;
        try {
          handle(*static_cast<const Message*>(samples[0]));
        } catch (...) {
          dds_return_loan(reader_, samples, n);
          throw;
        }
      }
      dds_return_loan(reader_, samples, n);
    }
  }
  std::uint32_t Publications() const {
    dds_subscription_matched_status_t status{};
    CheckDds(dds_get_subscription_matched_status(reader_, &status),
             "matched status of " + topic_name_);
    return status.current_count;
  }
  dds_entity_t handle() const { return reader_; }

 private:
  std::string topic_name_;
  dds_entity_t reader_;
};

}  // namespace fnmpc::ros2
