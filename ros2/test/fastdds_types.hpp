// SPDX-License-Identifier: BSD-3-Clause
// The Fast DDS side of the interoperability tests: message layouts written from the ROS 2
// field lists (plain CDR of the .msg fields, as rmw_fastrtps_cpp sends them), a type support
// for them, and a participant configured as a ROS 2 node on this machine would be. Shares no
// code with ros2/src.
#pragma once

#include <fastcdr/Cdr.h>
#include <fastcdr/FastBuffer.h>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/TopicDataType.hpp>

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace fnmpc_fastdds_peer {

using eprosima::fastcdr::Cdr;
namespace fdds = eprosima::fastdds::dds;
namespace rtps = eprosima::fastrtps::rtps;

// ---- Message layouts from the ROS 2 field lists (the rmw's plain CDR of the .msg fields).
struct Time {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
  void Write(Cdr& c) const { c << sec << nanosec; }
  void Read(Cdr& c) { c >> sec >> nanosec; }
};
struct Header {
  Time stamp;
  std::string frame_id;
  void Write(Cdr& c) const {
    stamp.Write(c);
    c << frame_id;
  }
  void Read(Cdr& c) {
    stamp.Read(c);
    c >> frame_id;
  }
};
struct Xyz {
  double x = 0, y = 0, z = 0;
  void Write(Cdr& c) const { c << x << y << z; }
  void Read(Cdr& c) { c >> x >> y >> z; }
};
struct Quat {
  double x = 0, y = 0, z = 0, w = 1;
  void Write(Cdr& c) const { c << x << y << z << w; }
  void Read(Cdr& c) { c >> x >> y >> z >> w; }
};
struct PoseStamped {
  static constexpr const char* kType = "geometry_msgs::msg::dds_::PoseStamped_";
  Header header;
  Xyz position;
  Quat orientation;
  void Write(Cdr& c) const {
    header.Write(c);
    position.Write(c);
    orientation.Write(c);
  }
  void Read(Cdr& c) {
    header.Read(c);
    position.Read(c);
    orientation.Read(c);
  }
};
struct Odometry {
  static constexpr const char* kType = "nav_msgs::msg::dds_::Odometry_";
  Header header;
  std::string child_frame_id;
  Xyz position;
  Quat orientation;
  std::array<double, 36> pose_covariance{};
  Xyz linear, angular;
  std::array<double, 36> twist_covariance{};
  void Read(Cdr& c) {
    header.Read(c);
    c >> child_frame_id;
    position.Read(c);
    orientation.Read(c);
    c >> pose_covariance;
    linear.Read(c);
    angular.Read(c);
    c >> twist_covariance;
  }
  void Write(Cdr&) const {}
};
struct Imu {
  static constexpr const char* kType = "sensor_msgs::msg::dds_::Imu_";
  Header header;
  Quat orientation;
  std::array<double, 9> orientation_covariance{};
  Xyz angular_velocity;
  std::array<double, 9> angular_velocity_covariance{};
  Xyz linear_acceleration;
  std::array<double, 9> linear_acceleration_covariance{};
  void Read(Cdr& c) {
    header.Read(c);
    orientation.Read(c);
    c >> orientation_covariance;
    angular_velocity.Read(c);
    c >> angular_velocity_covariance;
    linear_acceleration.Read(c);
    c >> linear_acceleration_covariance;
  }
  void Write(Cdr&) const {}
};
struct Setpoint {
  static constexpr const char* kType = "fnmpc_msgs::msg::dds_::AttitudeThrustSetpoint_";
  Header header;
  double thrust = 0, throttle = 0, roll = 0, pitch = 0, yaw = 0;
  std::string phase;
  void Read(Cdr& c) {
    header.Read(c);
    c >> thrust >> throttle >> roll >> pitch >> yaw >> phase;
  }
  void Write(Cdr& c) const {
    header.Write(c);
    c << thrust << throttle << roll << pitch << yaw << phase;
  }
};
struct SimSync {
  static constexpr const char* kType = "fnmpc_msgs::msg::dds_::SimSync_";
  Header header;
  std::uint64_t measurements = 0, first = 0;
  std::vector<std::uint8_t> order;
  void Read(Cdr& c) {
    header.Read(c);
    c >> measurements >> first >> order;
  }
  void Write(Cdr&) const {}
};
struct OpticalFlow {
  static constexpr const char* kType = "fnmpc_msgs::msg::dds_::OpticalFlow_";
  Header header;
  Xyz velocity;
  void Read(Cdr& c) {
    header.Read(c);
    velocity.Read(c);
  }
  void Write(Cdr&) const {}
};
struct Heading {
  static constexpr const char* kType = "fnmpc_msgs::msg::dds_::Heading_";
  Header header;
  double yaw = 0;
  void Read(Cdr& c) {
    header.Read(c);
    c >> yaw;
  }
  void Write(Cdr&) const {}
};
// The leading fields only (a reader need not consume the whole sample).
struct BatteryState {
  static constexpr const char* kType = "sensor_msgs::msg::dds_::BatteryState_";
  Header header;
  float voltage = 0;
  void Read(Cdr& c) {
    header.Read(c);
    c >> voltage;
  }
  void Write(Cdr&) const {}
};
struct RelativeObservation {
  static constexpr const char* kType = "fnmpc_msgs::msg::dds_::RelativeObservation_";
  Header header;
  std::int32_t neighbour_id = 0;
  double range = 0, bearing = 0, elevation = 0, relative_yaw = 0;
  void Read(Cdr& c) {
    header.Read(c);
    c >> neighbour_id >> range >> bearing >> elevation >> relative_yaw;
  }
  void Write(Cdr&) const {}
};
struct Clock {
  static constexpr const char* kType = "rosgraph_msgs::msg::dds_::Clock_";
  Time clock;
  void Read(Cdr& c) { clock.Read(c); }
  void Write(Cdr&) const {}
};

template <typename M>
class CdrType : public fdds::TopicDataType {
 public:
  CdrType() {
    setName(M::kType);
    m_typeSize = 65536;  // a SimSync carries a control period's delivery order
    m_isGetKeyDefined = false;
  }
  bool serialize(void* data, rtps::SerializedPayload_t* payload) override {
    eprosima::fastcdr::FastBuffer buffer(reinterpret_cast<char*>(payload->data), payload->max_size);
    Cdr cdr(buffer, Cdr::LITTLE_ENDIANNESS, Cdr::DDS_CDR);
    payload->encapsulation = CDR_LE;
    cdr.serialize_encapsulation();
    static_cast<const M*>(data)->Write(cdr);
    payload->length = static_cast<std::uint32_t>(cdr.getSerializedDataLength());
    return true;
  }
  bool deserialize(rtps::SerializedPayload_t* payload, void* data) override {
    eprosima::fastcdr::FastBuffer buffer(reinterpret_cast<char*>(payload->data), payload->length);
    Cdr cdr(buffer, Cdr::DEFAULT_ENDIAN, Cdr::DDS_CDR);
    cdr.read_encapsulation();
    static_cast<M*>(data)->Read(cdr);
    return true;
  }
  std::function<std::uint32_t()> getSerializedSizeProvider(void*) override {
    return [] { return 65536u; };
  }
  void* createData() override { return new M(); }
  void deleteData(void* data) override { delete static_cast<M*>(data); }
  bool getKey(void*, rtps::InstanceHandle_t*, bool) override { return false; }
};

struct Discovered {
  std::string type;
  bool reliable = false;
  bool volatile_durability = false;
  std::string user_data;
};

class DiscoveryListener : public fdds::DomainParticipantListener {
 public:
  void on_publisher_discovery(fdds::DomainParticipant*, rtps::WriterDiscoveryInfo&& info) override {
    if (info.status != rtps::WriterDiscoveryInfo::DISCOVERED_WRITER) return;
    Discovered d;
    d.type = info.info.typeName().to_string();
    d.reliable = info.info.m_qos.m_reliability.kind == fdds::RELIABLE_RELIABILITY_QOS;
    d.volatile_durability = info.info.m_qos.m_durability.kind == fdds::VOLATILE_DURABILITY_QOS;
    const auto& bytes = info.info.m_qos.m_userData.data_vec();
    d.user_data.assign(bytes.begin(), bytes.end());
    std::lock_guard<std::mutex> lock(mutex);
    writers[info.info.topicName().to_string()] = d;
  }
  std::mutex mutex;
  std::map<std::string, Discovered> writers;
};

template <typename F>
inline bool WaitFor(F done) {
  for (int i = 0; i < 1500; ++i) {  // at most 15 s: discovery over UDP takes ~0.1-1 s
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

// A Fast DDS participant as a ROS 2 node on this machine would be configured: UDP on
// loopback, 127.0.0.1 as initial peer (no shared memory: that only talks to Fast DDS).
class FastDdsSide {
 public:
  explicit FastDdsSide(int domain) {
    fdds::DomainParticipantQos qos;
    qos.name("fastdds_ros2_peer");
    qos.transport().use_builtin_transports = false;
    auto udp = std::make_shared<eprosima::fastdds::rtps::UDPv4TransportDescriptor>();
    udp->interfaceWhiteList.emplace_back("127.0.0.1");
    qos.transport().user_transports.push_back(udp);
    rtps::Locator_t peer;
    rtps::IPLocator::setIPv4(peer, 127, 0, 0, 1);
    qos.wire_protocol().builtin.initialPeersList.push_back(peer);
    participant_ = fdds::DomainParticipantFactory::get_instance()->create_participant(
        domain, qos, &listener);  // the discovery callbacks need the full mask
    subscriber_ = participant_->create_subscriber(fdds::SUBSCRIBER_QOS_DEFAULT);
    publisher_ = participant_->create_publisher(fdds::PUBLISHER_QOS_DEFAULT);
  }
  ~FastDdsSide() {
    participant_->delete_contained_entities();
    fdds::DomainParticipantFactory::get_instance()->delete_participant(participant_);
  }
  bool ok() const { return participant_ && subscriber_ && publisher_; }

  template <typename M>
  fdds::Topic* Topic(const std::string& name) {
    fdds::TypeSupport type(new CdrType<M>());
    type.register_type(participant_);
    return participant_->create_topic(name, M::kType, fdds::TOPIC_QOS_DEFAULT);
  }
  template <typename M>
  fdds::DataReader* Reader(const std::string& name, bool reliable, int depth) {
    fdds::DataReaderQos qos = fdds::DATAREADER_QOS_DEFAULT;
    qos.reliability().kind =
        reliable ? fdds::RELIABLE_RELIABILITY_QOS : fdds::BEST_EFFORT_RELIABILITY_QOS;
    qos.durability().kind = fdds::VOLATILE_DURABILITY_QOS;
    qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
    qos.history().depth = depth;
    return subscriber_->create_datareader(Topic<M>(name), qos);
  }
  template <typename M>
  fdds::DataWriter* Writer(const std::string& name, const std::string& type_hash) {
    fdds::DataWriterQos qos = fdds::DATAWRITER_QOS_DEFAULT;
    qos.reliability().kind = fdds::RELIABLE_RELIABILITY_QOS;
    qos.durability().kind = fdds::VOLATILE_DURABILITY_QOS;
    qos.history().kind = fdds::KEEP_LAST_HISTORY_QOS;
    qos.history().depth = 10;
    const std::string user = "typehash=" + type_hash + ";";
    qos.user_data().data_vec(
        std::vector<eprosima::fastrtps::rtps::octet>(user.begin(), user.end()));
    return publisher_->create_datawriter(Topic<M>(name), qos);
  }

  DiscoveryListener listener;

 private:
  fdds::DomainParticipant* participant_ = nullptr;
  fdds::Subscriber* subscriber_ = nullptr;
  fdds::Publisher* publisher_ = nullptr;
};

template <typename M>
inline bool TakeOne(fdds::DataReader* reader, M* out) {
  fdds::SampleInfo info;
  while (reader->take_next_sample(out, &info) == ReturnCode_t::RETCODE_OK) {
    if (info.valid_data) return true;
  }
  return false;
}

}  // namespace fnmpc_fastdds_peer
