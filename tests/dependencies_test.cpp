// Every system dependency the build finds (cmake/Dependencies.cmake) links and does real work,
// so that a broken package or imported target shows up here, not in a later component.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_2.h>
#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <gtest/gtest.h>
#include <libsumo/Simulation.h>
#include <ode/ode.h>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

namespace {

TEST(Dependencies, CgalComputesAPolygonArea) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  CGAL::Polygon_2<K> square;
  square.push_back(K::Point_2(0, 0));
  square.push_back(K::Point_2(0.585, 0));
  square.push_back(K::Point_2(0.585, 0.585));
  square.push_back(K::Point_2(0, 0.585));
  EXPECT_NEAR(CGAL::to_double(square.area()), 0.585 * 0.585, 1e-12);
  EXPECT_TRUE(square.is_simple());
}

TEST(Dependencies, OdeDropsABodyUnderGravity) {
  ASSERT_NE(dInitODE2(0), 0);
  const dWorldID world = dWorldCreate();
  dWorldSetGravity(world, 0, 0, -9.81);
  const dBodyID body = dBodyCreate(world);
  dMass mass;
  dMassSetBoxTotal(&mass, 2.68, 0.318, 0.175, 0.257);
  dBodySetMass(body, &mass);
  for (int i = 0; i < 100; ++i) dWorldStep(world, 0.01);
  EXPECT_NEAR(dBodyGetLinearVel(body)[2], -9.81, 1e-6);  // 1 s of free fall
  dWorldDestroy(world);
  dCloseODE();
}

TEST(Dependencies, AprilTagDetectsARenderedTag36h11WithOpenCv) {
  apriltag_family_t* family = tag36h11_create();
  image_u8_t* tag = apriltag_to_image(family, 7);  // 10x10 px incl. the white border
  ASSERT_NE(tag, nullptr);
  // Scale the tag up with OpenCV onto a white canvas, as a camera would see it.
  cv::Mat small(tag->height, tag->width, CV_8UC1, tag->buf, static_cast<size_t>(tag->stride));
  cv::Mat big;
  cv::resize(small, big, cv::Size(), 20, 20, cv::INTER_NEAREST);
  cv::Mat canvas(400, 400, CV_8UC1, cv::Scalar(255));
  big.copyTo(canvas(cv::Rect(100, 100, big.cols, big.rows)));
  image_u8_t frame{canvas.cols, canvas.rows, static_cast<int32_t>(canvas.step), canvas.data};

  apriltag_detector_t* detector = apriltag_detector_create();
  apriltag_detector_add_family(detector, family);
  zarray_t* detections = apriltag_detector_detect(detector, &frame);
  ASSERT_EQ(zarray_size(detections), 1);
  apriltag_detection_t* d = nullptr;
  zarray_get(detections, 0, &d);
  EXPECT_EQ(d->id, 7);
  EXPECT_NEAR(d->c[0], 100 + big.cols / 2.0, 2.0);
  apriltag_detections_destroy(detections);
  apriltag_detector_destroy(detector);
  image_u8_destroy(tag);
  tag36h11_destroy(family);
}

TEST(Dependencies, LibsumoLinksAndReportsNoSimulationLoaded) {
  EXPECT_FALSE(libsumo::Simulation::isLoaded());
}

TEST(Dependencies, EigenComposesRotations) {
  const Eigen::AngleAxisd a(0.5, Eigen::Vector3d::UnitZ());
  EXPECT_NEAR(Eigen::AngleAxisd(a * a).angle(), 1.0, 1e-12);
}

}  // namespace
