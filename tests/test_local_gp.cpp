// Batches of local GP models on an OpenCL device (integrate/local_gp_batch.hpp, kernels/local_gp.cl;
// PoCL here) against the CPU path's Eigen solve (gp_predict), and gpom/wgpom built with either:
// the device factors and solves in another order, so they agree to rounding, within 1e-9.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"
#include "integrate/local_gp_batch.hpp"
#include "methods/gp/gp_regression.hpp"
#include "methods/gpom/gpom_method.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

std::unique_ptr<LocalGpDevice> opencl_device(std::string& why) {
  try {
    return opencl_detail::make_opencl_local_gp(BackendOptions{"opencl", "", 2});
  } catch (const OpenClUnavailable& e) {
    why = e.what();
    return nullptr;
  }
}

struct Model {
  std::vector<Vec3d> train;
  std::vector<double> labels;
  Vec3d query;
};

// Models of 1 to max_n inputs scattered within 1.5 m of their query, labels +-1.
std::vector<Model> random_models(int count, int max_n, std::mt19937& rng) {
  std::uniform_int_distribution<int> size(1, max_n), label(0, 1);
  std::uniform_real_distribution<double> offset(-1.5, 1.5), place(-50, 50);
  std::vector<Model> models(static_cast<size_t>(count));
  for (Model& m : models) {
    m.query = {place(rng), place(rng), place(rng)};
    const int n = size(rng);
    for (int i = 0; i < n; ++i) {
      m.train.push_back({m.query.x + offset(rng), m.query.y + offset(rng), m.query.z + offset(rng)});
      m.labels.push_back(label(rng) ? 1.0 : -1.0);
    }
  }
  return models;
}

LocalGpBatch batch_of(const std::vector<Model>& models, int max_n) {
  LocalGpBatch batch;
  batch.max_n = max_n;
  for (const Model& m : models) batch.add(m.train, m.labels, m.query);
  return batch;
}

TEST(LocalGp, OpenClEqualsTheCpuSolveToRounding) {
  std::string why;
  std::unique_ptr<LocalGpDevice> device = opencl_device(why);
  if (!device) GTEST_SKIP() << "no OpenCL device with double precision: " << why;
  std::mt19937 rng(5);
  for (const GpCovariance covariance : {GpCovariance::kMatern32, GpCovariance::kSparse}) {
    GpHyperParams hp;
    hp.covariance = covariance;
    hp.ell_m = 0.8;
    hp.signal_var = 1.3;
    hp.noise_std = 0.1;
    const int max_n = 60;  // gpom's 2k for k = 30
    const std::vector<Model> models = random_models(300, max_n, rng);
    std::vector<double> mean(models.size()), variance(models.size());
    ASSERT_TRUE(device->predict(batch_of(models, max_n), {static_cast<int>(covariance), hp.ell_m, hp.signal_var, 0.01},
                                mean.data(), variance.data()));
    double worst = 0;
    for (size_t q = 0; q < models.size(); ++q) {
      const GpPrediction cpu = gp_predict(models[q].train, models[q].labels, {models[q].query}, hp)[0];
      ASSERT_NEAR(mean[q], cpu.mean, 1e-9) << "model " << q << " of " << models[q].train.size() << " inputs";
      ASSERT_NEAR(variance[q], cpu.variance, 1e-9) << "model " << q;
      worst = std::max({worst, std::abs(mean[q] - cpu.mean), std::abs(variance[q] - cpu.variance)});
    }
    std::printf("covariance %d: %zu models, largest difference %.3g\n", static_cast<int>(covariance), models.size(),
                worst);
  }
  EXPECT_EQ(device->info().name, "opencl");
}

TEST(LocalGp, AMatrixThatIsNotPositiveDefiniteGivesNaN) {
  std::string why;
  std::unique_ptr<LocalGpDevice> device = opencl_device(why);
  if (!device) GTEST_SKIP() << "no OpenCL device with double precision: " << why;
  // Two equal inputs and no noise: K is singular.
  const std::vector<Model> models = {{{{0, 0, 0}, {0, 0, 0}}, {1, -1}, {0.1, 0, 0}}, {{{0, 0, 0}}, {1}, {0.1, 0, 0}}};
  std::vector<double> mean(2), variance(2);
  ASSERT_TRUE(device->predict(batch_of(models, 4), {static_cast<int>(GpCovariance::kMatern32), 0.5, 1.0, 0.0}, mean.data(),
                              variance.data()));
  EXPECT_TRUE(std::isnan(mean[0]));
  EXPECT_TRUE(std::isfinite(mean[1]));
}

TEST(LocalGp, TheDeviceIsChosenAsTheBackendSays) {
  const auto on = [](const char* backend, const char* filter) {
    return make_local_gp_device(ComputeDevice::choose(BackendOptions{backend, filter, 1}));
  };
  const std::unique_ptr<LocalGpDevice> cpu = on("cpu", "");
  EXPECT_EQ(cpu->info().kind, DeviceKind::kCpu);
  EXPECT_EQ(cpu->info().note, "");
  LocalGpBatch none;
  EXPECT_FALSE(cpu->predict(none, LocalGpCovariance{}, nullptr, nullptr));  // the caller solves them
  const std::unique_ptr<LocalGpDevice> missing = on("opencl", "no such device anywhere");
  EXPECT_EQ(missing->info().kind, DeviceKind::kCpu);
  EXPECT_NE(missing->info().note.find("no such device anywhere"), std::string::npos) << missing->info().note;
  EXPECT_NE(missing->info().note.find("using the CPU path"), std::string::npos) << missing->info().note;
  EXPECT_THROW(on("gpu", ""), std::invalid_argument);
  // auto takes a GPU only; PoCL's CPU device is slower than the CPU path.
  std::string why;
  if (opencl_device(why)) {
    const std::unique_ptr<LocalGpDevice> chosen = on("auto", "");
    bool gpu = false;  // the device auto picks: a GPU where there is one
    for (const OpenClDeviceInfo& d : list_opencl_devices()) gpu = gpu || d.type == "GPU";
    EXPECT_EQ(chosen->info().kind == DeviceKind::kOpenCl, gpu);
    EXPECT_EQ(chosen->info().note, "");
    if (!gpu) {
      EXPECT_NE(chosen->info().reason.find("is not a GPU"), std::string::npos) << chosen->info().reason;
    }
  }
}

// The maps the device tests build: 0.1 m cells, 4 m range; l = 0.4 m.
BuildParams device_test_params() {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  params.preprocess.max_range_m = 4;
  return params;
}
MethodParams device_test_method_params() {
  MethodParams mp;
  mp.set("gp-length", 0.4);
  return mp;
}

// Two random scans flattened onto the plane z = 0.05 (planar: gpom maps one layer).
std::vector<Scan> planar_scans(int points_per_scan) {
  std::vector<Scan> scans = testing::random_scans(3, 2, points_per_scan, 1.5f);
  for (Scan& scan : scans) {
    scan.pose.position.z = 0.05f;
    for (Vec3f& p : scan.points) p.z = 0.05f;
  }
  return scans;
}

struct CpuAndDevice {
  std::unique_ptr<MappingMethod> cpu, device;
};

// `name` built from `scans` twice: with the CPU back end and with the OpenCL one.
CpuAndDevice built_both_ways(const std::string& name, const BuildParams& params, const MethodParams& mp,
                             const std::vector<Scan>& scans) {
  CpuAndDevice built{make_method(name, params, mp, testing::cpu_backend()),
                     make_method(name, params, mp, BackendOptions{"opencl", "", 2})};
  for (const Scan& scan : scans) {
    built.cpu->insert(scan);
    built.device->insert(scan);
  }
  built.cpu->finish();
  built.device->finish();
  return built;
}

// Every cell of an n^3 (or, at one z, n^2) grid of 0.1 m cells about the origin: the same cells
// known, means and variances within `tolerance` (0: equal). Returns the known cells compared.
size_t compare_cells(MappingMethod& a, MappingMethod& b, int half, bool planar, double tolerance) {
  size_t known = 0;
  for (int z = planar ? 0 : -half; z < (planar ? 1 : half); ++z)
    for (int y = -half; y < half; ++y)
      for (int x = -half; x < half; ++x) {
        const double px = (x + 0.5) * 0.1, py = (y + 0.5) * 0.1, pz = planar ? 0.05 : (z + 0.5) * 0.1;
        const auto ea = a.estimate(px, py, pz), eb = b.estimate(px, py, pz);
        EXPECT_EQ(ea.has_value(), eb.has_value()) << px << ", " << py << ", " << pz;
        if (!ea || !eb) continue;
        ++known;
        EXPECT_NEAR(*ea->gp_mean, *eb->gp_mean, tolerance) << px << ", " << py << ", " << pz;
        EXPECT_NEAR(*ea->variance, *eb->variance, tolerance) << px << ", " << py << ", " << pz;
        EXPECT_NEAR(ea->occupancy, eb->occupancy, tolerance) << px << ", " << py << ", " << pz;
      }
  return known;
}

// gpom and wgpom on two planar scans, with the local models solved on the device and on the CPU:
// every cell's mean and variance within 1e-9, the same cells known.
TEST(LocalGp, GpomAndWgpomMapsOnTheDeviceAreTheCpuMaps) {
  std::string why;
  if (!opencl_device(why)) GTEST_SKIP() << "no OpenCL device with double precision: " << why;
  BuildParams params = device_test_params();
  MethodParams mp = device_test_method_params();
  const std::vector<Scan> scans = planar_scans(400);
  for (const std::string name : {"gpom", "wgpom"}) {
    const CpuAndDevice built = built_both_ways(name, params, mp, scans);
    ASSERT_EQ(built.device->backend().name, "opencl") << built.device->backend().note;
    const size_t known = compare_cells(*built.cpu, *built.device, 40, true, 1e-9);
    std::printf("%s: %zu known cells compared\n", name.c_str(), known);
    EXPECT_GT(known, 500u);
  }
}

// The squared exponential on the device is the CPU's (gp_kernel_math.h's shared selector); the
// expected kernel (--pose-fusion kernel) is solved on the CPU whatever the back end: the same map,
// bit for bit, reported as the CPU's.
TEST(LocalGp, SquaredExponentialOnTheDeviceAndTheExpectedKernelOnTheCpu) {
  std::string why;
  if (!opencl_device(why)) GTEST_SKIP() << "no OpenCL device with double precision: " << why;
  BuildParams params = device_test_params();
  MethodParams mp = device_test_method_params();
  mp.set("gp-covariance", "se");
  std::vector<Scan> scans = planar_scans(200);
  for (const bool expected_kernel : {false, true}) {
    if (expected_kernel) {
      params.preprocess.pose_fusion = PoseFusion::kExpectedKernel;
      scans[1].pose_covariance = PoseCovariance::from_planar({0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.001});
    }
    const CpuAndDevice built = built_both_ways("gpom", params, mp, scans);
    EXPECT_EQ(built.device->backend().name, expected_kernel ? "cpu" : "opencl") << built.device->backend().device;
    EXPECT_GT(compare_cells(*built.cpu, *built.device, 40, true, expected_kernel ? 0.0 : 1e-9), 300u) << expected_kernel;
  }
}

// The neural-network covariance is not a function of the distance: with an OpenCL back end its
// local models are solved on the CPU, the CPU back end's map bit for bit, reported as the CPU's.
TEST(LocalGp, NeuralNetworkCovarianceStaysOnTheCpu) {
  std::string why;
  if (!opencl_device(why)) GTEST_SKIP() << "no OpenCL device with double precision: " << why;
  BuildParams params = device_test_params();
  MethodParams mp = device_test_method_params();
  mp.set("gp-covariance", "nn");
  const CpuAndDevice built = built_both_ways("gpom", params, mp, testing::random_scans(3, 2, 200, 1.5f));
  EXPECT_EQ(built.device->backend().name, "cpu") << built.device->backend().device;
  EXPECT_NE(built.device->backend().device.find("solved on the CPU"), std::string::npos) << built.device->backend().device;
  EXPECT_GT(compare_cells(*built.cpu, *built.device, 20, false, 0.0), 300u);
}

}  // namespace
}  // namespace bgkmap
