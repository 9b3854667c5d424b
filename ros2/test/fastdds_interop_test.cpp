// SPDX-License-Identifier: BSD-3-Clause
// Against an independent DDS implementation: eProsima Fast DDS (Debian's libfastrtps 2.9), with
// the message layouts written here by hand from the ROS 2 conventions only (topic "rt/<name>",
// type "<pkg>::msg::dds_::<Name>_", plain CDR little-endian, the ROS 2 QoS profiles), i.e. what a
// ROS 2 node on rmw_fastrtps_cpp does. It shares no code with the Cyclone side but the test.
//  * Our Cyclone writers publish Odometry (default QoS), Imu (sensor data) and the fnmpc
//    attitude/thrust setpoint; Fast DDS discovers them with the right topic and type names,
//    reliability, durability and USER_DATA type hash, and receives the field values.
//  * A Fast DDS writer publishes a PoseStamped waypoint; our Cyclone reader receives it.
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
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "dds_node.hpp"

namespace {

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
  void Write(Cdr&) const {}
};

template <typename M>
class CdrType : public fdds::TopicDataType {
 public:
  CdrType() {
    setName(M::kType);
    m_typeSize = 4096;
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
    return [] { return 4096u; };
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
bool WaitFor(F done) {
  for (int i = 0; i < 1500; ++i) {  // at most 15 s: discovery over UDP takes ~0.1-1 s
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

constexpr int kDomain = 62;

// A Fast DDS participant as a ROS 2 node on this machine would be configured: UDP on
// loopback, 127.0.0.1 as initial peer (no shared memory: that only talks to Fast DDS).
class FastDdsSide {
 public:
  FastDdsSide() {
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
        kDomain, qos, &listener);  // the discovery callbacks need the full mask
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
bool TakeOne(fdds::DataReader* reader, M* out) {
  fdds::SampleInfo info;
  while (reader->take_next_sample(out, &info) == ReturnCode_t::RETCODE_OK) {
    if (info.valid_data) return true;
  }
  return false;
}

class FastDdsInterop : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    setenv("CYCLONEDDS_URI", "file://" FNMPC_ROS2_LOOPBACK_CONFIG, 1);
    setenv("ROS_DOMAIN_ID", std::to_string(kDomain).c_str(), 1);
  }
};

TEST_F(FastDdsInterop, FastDdsReceivesOurTopicsWithTheRos2Conventions) {
  using namespace fnmpc::ros2;
  Participant cyclone;
  Writer<nav_msgs_msg_dds__Odometry_> odom(cyclone, "rt/leader/odom", QosProfile::Default());
  Writer<sensor_msgs_msg_dds__Imu_> imu(cyclone, "rt/leader/imu", QosProfile::SensorData());
  Writer<fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_> setpoint(cyclone, "rt/leader/setpoint",
                                                               QosProfile::Default());
  FastDdsSide fast;
  ASSERT_TRUE(fast.ok());
  auto* odom_reader = fast.Reader<Odometry>("rt/leader/odom", true, 10);
  auto* imu_reader = fast.Reader<Imu>("rt/leader/imu", false, 5);
  auto* setpoint_reader = fast.Reader<Setpoint>("rt/leader/setpoint", true, 10);
  ASSERT_TRUE(odom_reader && imu_reader && setpoint_reader);
  // Both sides' discovery: Cyclone matched the readers, Fast DDS reported the writers.
  ASSERT_TRUE(WaitFor([&] {
    std::lock_guard<std::mutex> lock(fast.listener.mutex);
    return odom.Subscriptions() == 1 && imu.Subscriptions() == 1 && setpoint.Subscriptions() == 1 &&
           fast.listener.writers.size() >= 3;
  })) << "Cyclone writers and Fast DDS readers did not discover each other";

  {
    std::lock_guard<std::mutex> lock(fast.listener.mutex);
    const auto& w = fast.listener.writers;
    ASSERT_EQ(w.count("rt/leader/odom"), 1u);
    EXPECT_EQ(w.at("rt/leader/odom").type, "nav_msgs::msg::dds_::Odometry_");
    EXPECT_TRUE(w.at("rt/leader/odom").reliable);
    EXPECT_TRUE(w.at("rt/leader/odom").volatile_durability);
    EXPECT_EQ(w.at("rt/leader/odom").user_data,
              std::string("typehash=") + Ros2Type<nav_msgs_msg_dds__Odometry_>::kTypeHash + ";");
    ASSERT_EQ(w.count("rt/leader/imu"), 1u);
    EXPECT_EQ(w.at("rt/leader/imu").type, "sensor_msgs::msg::dds_::Imu_");
    EXPECT_FALSE(w.at("rt/leader/imu").reliable);
    ASSERT_EQ(w.count("rt/leader/setpoint"), 1u);
    EXPECT_EQ(w.at("rt/leader/setpoint").type, "fnmpc_msgs::msg::dds_::AttitudeThrustSetpoint_");
  }

  nav_msgs_msg_dds__Odometry_ o{};
  o.header.stamp = ToRosTime(7.125);
  o.header.frame_id = const_cast<char*>("world");
  o.child_frame_id = const_cast<char*>("leader/base_link");
  o.pose.pose.position = {1.5, -0.25, 2.0};
  o.pose.pose.orientation = {0.0, 0.0, 0.6, 0.8};
  o.pose.covariance[35] = 0.01;
  o.twist.twist.linear = {0.5, 0.0, -0.1};
  o.twist.covariance[0] = 0.2;
  sensor_msgs_msg_dds__Imu_ i{};
  i.header.stamp = ToRosTime(7.13);
  i.header.frame_id = const_cast<char*>("leader/base_link");
  i.orientation.w = 1.0;
  i.orientation_covariance[0] = -1.0;  // ROS: orientation not provided
  i.angular_velocity = {0.01, -0.02, 0.3};
  i.linear_acceleration = {0.0, 0.1, 9.81};
  fnmpc_msgs_msg_dds__AttitudeThrustSetpoint_ s{};
  s.header.stamp = ToRosTime(7.1);
  s.header.frame_id = const_cast<char*>("");
  s.thrust = 7.4;
  s.throttle = std::numeric_limits<double>::quiet_NaN();
  s.roll = 0.05;
  s.pitch = -0.04;
  s.yaw = 1.2;
  s.phase = const_cast<char*>("nmpc");

  Odometry got_odom;
  Imu got_imu;
  Setpoint got_setpoint;
  bool have_odom = false, have_imu = false, have_setpoint = false;
  // Best effort may drop a sample: publish until each arrived (bounded).
  ASSERT_TRUE(WaitFor([&] {
    if (!have_odom) odom.Write(o);
    if (!have_imu) imu.Write(i);
    if (!have_setpoint) setpoint.Write(s);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    have_odom = have_odom || TakeOne(odom_reader, &got_odom);
    have_imu = have_imu || TakeOne(imu_reader, &got_imu);
    have_setpoint = have_setpoint || TakeOne(setpoint_reader, &got_setpoint);
    return have_odom && have_imu && have_setpoint;
  }));
  EXPECT_EQ(got_odom.header.stamp.sec, 7);
  EXPECT_EQ(got_odom.header.stamp.nanosec, 125000000u);
  EXPECT_EQ(got_odom.header.frame_id, "world");
  EXPECT_EQ(got_odom.child_frame_id, "leader/base_link");
  EXPECT_EQ(got_odom.position.x, 1.5);
  EXPECT_EQ(got_odom.position.y, -0.25);
  EXPECT_EQ(got_odom.orientation.z, 0.6);
  EXPECT_EQ(got_odom.pose_covariance[35], 0.01);
  EXPECT_EQ(got_odom.linear.z, -0.1);
  EXPECT_EQ(got_odom.twist_covariance[0], 0.2);
  EXPECT_EQ(got_imu.header.frame_id, "leader/base_link");
  EXPECT_EQ(got_imu.orientation_covariance[0], -1.0);
  EXPECT_EQ(got_imu.angular_velocity.z, 0.3);
  EXPECT_EQ(got_imu.linear_acceleration.z, 9.81);
  EXPECT_EQ(got_setpoint.thrust, 7.4);
  EXPECT_TRUE(std::isnan(got_setpoint.throttle));
  EXPECT_EQ(got_setpoint.pitch, -0.04);
  EXPECT_EQ(got_setpoint.yaw, 1.2);
  EXPECT_EQ(got_setpoint.phase, "nmpc");
}

TEST_F(FastDdsInterop, OurReaderReceivesAFastDdsWaypoint) {
  using namespace fnmpc::ros2;
  Participant cyclone;
  Reader<geometry_msgs_msg_dds__PoseStamped_> reader(cyclone, "rt/leader/waypoint",
                                                     QosProfile::Default());
  FastDdsSide fast;
  ASSERT_TRUE(fast.ok());
  auto* writer = fast.Writer<PoseStamped>("rt/leader/waypoint",
                                          Ros2Type<geometry_msgs_msg_dds__PoseStamped_>::kTypeHash);
  ASSERT_NE(writer, nullptr);
  // Both sides matched: a write before the Fast DDS writer knows our reader would be lost.
  ASSERT_TRUE(WaitFor([&] {
    fdds::PublicationMatchedStatus status;
    writer->get_publication_matched_status(status);
    return reader.Publications() == 1 && status.current_count == 1;
  })) << "Fast DDS writer and Cyclone reader did not discover each other";
  PoseStamped p;
  p.header.stamp = {12, 500};
  p.header.frame_id = "world";
  p.position = {3.0, 4.0, 1.25};
  p.orientation = {0.0, 0.0, 0.0, 1.0};
  ASSERT_TRUE(writer->write(&p));
  int received = 0;
  ASSERT_TRUE(WaitFor([&] {
    reader.TakeAll([&](const geometry_msgs_msg_dds__PoseStamped_& m) {
      ++received;
      EXPECT_EQ(m.header.stamp.sec, 12);
      EXPECT_EQ(m.header.stamp.nanosec, 500u);
      EXPECT_STREQ(m.header.frame_id, "world");
      EXPECT_EQ(m.pose.position.x, 3.0);
      EXPECT_EQ(m.pose.position.y, 4.0);
      EXPECT_EQ(m.pose.position.z, 1.25);
      EXPECT_EQ(m.pose.orientation.w, 1.0);
    });
    return received > 0;
  }));
  EXPECT_EQ(received, 1);
}

}  // namespace
