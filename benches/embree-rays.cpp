// Embree's speed on a ray file that `lightpath render --record-rays DIR` wrote: the
// path tracer's own closest-hit rays (DIR/paths.rays) and shadow rays (DIR/shadow.rays)
// against its triangles (DIR/scene.obj), ray by ray (rtcIntersect1, rtcOccluded1) and
// in packets of sixteen consecutive rays (rtcIntersect16, rtcOccluded16), as
// `lightpath bench DIR/scene.obj --rays DIR --packet` traces them. Prints JSON with the
// keys of `lightpath bench --json` (traversal.{st,mt}.SET and traversal.{st,mt}.packet.SET).
//
//     g++ -O2 -march=native -std=c++17 -o embree-rays benches/embree-rays.cpp -lembree3 -lpthread
//     ./embree-rays DIR [--reps 5] [--threads N] [--robust]
//
// benches/path-rays.py builds and runs it, alternating with `lightpath bench`.
#include <embree3/rtcore.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

struct RayRecord {
  float ox, oy, oz, tmin, dx, dy, dz, tmax;
};

[[noreturn]] void fail(const std::string& what) {
  std::fprintf(stderr, "embree-rays: %s\n", what.c_str());
  std::exit(1);
}

std::vector<RayRecord> read_rays(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) fail("cannot open " + path);
  std::vector<char> bytes((std::istreambuf_iterator<char>(f)), {});
  if (bytes.size() % sizeof(RayRecord) != 0) fail(path + ": not whole 32-byte ray records");
  std::vector<RayRecord> rays(bytes.size() / sizeof(RayRecord));
  std::memcpy(rays.data(), bytes.data(), bytes.size());
  return rays;
}

// The `v` and `f` lines of an OBJ of triangles (faces as 1-based vertex indices).
void read_obj(const std::string& path, std::vector<float>& v, std::vector<unsigned>& f) {
  std::ifstream in(path);
  if (!in) fail("cannot open " + path);
  std::string line;
  size_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    std::istringstream s(line);
    std::string tag;
    s >> tag;
    if (tag == "v") {
      float x, y, z;
      if (!(s >> x >> y >> z)) fail(path + ":" + std::to_string(number) + ": bad vertex");
      v.insert(v.end(), {x, y, z});
    } else if (tag == "f") {
      long a, b, c;
      if (!(s >> a >> b >> c)) fail(path + ":" + std::to_string(number) + ": bad face");
      for (long i : {a, b, c}) {
        if (i < 1 || size_t(i) > v.size() / 3) fail(path + ":" + std::to_string(number) + ": bad index");
        f.push_back(unsigned(i - 1));
      }
    }
  }
}

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Hits (or occluded rays) of rays [begin, end), ray by ray or sixteen at a time.
long trace(RTCScene scene, const std::vector<RayRecord>& rays, size_t begin, size_t end, bool occluded,
           bool packet) {
  long count = 0;
  RTCIntersectContext ctx;
  if (!packet) {
    for (size_t i = begin; i < end; ++i) {
      const RayRecord& r = rays[i];
      RTCRayHit rh;
      rh.ray = {r.ox, r.oy, r.oz, r.tmin, r.dx, r.dy, r.dz, 0.0f, r.tmax, 0xffffffffu, 0, 0};
      rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
      rtcInitIntersectContext(&ctx);
      if (occluded) {
        rtcOccluded1(scene, &ctx, &rh.ray);
        count += rh.ray.tfar < 0.0f;
      } else {
        rtcIntersect1(scene, &ctx, &rh);
        count += rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
      }
    }
    return count;
  }
  for (size_t at = begin; at < end; at += 16) {
    const size_t n = std::min<size_t>(16, end - at);
    alignas(64) RTCRayHit16 rh;
    alignas(64) int valid[16];
    for (size_t l = 0; l < 16; ++l) {
      const RayRecord& r = rays[at + (l < n ? l : 0)];
      valid[l] = l < n ? -1 : 0;
      rh.ray.org_x[l] = r.ox;
      rh.ray.org_y[l] = r.oy;
      rh.ray.org_z[l] = r.oz;
      rh.ray.tnear[l] = r.tmin;
      rh.ray.dir_x[l] = r.dx;
      rh.ray.dir_y[l] = r.dy;
      rh.ray.dir_z[l] = r.dz;
      rh.ray.time[l] = 0.0f;
      rh.ray.tfar[l] = r.tmax;
      rh.ray.mask[l] = 0xffffffffu;
      rh.ray.id[l] = 0;
      rh.ray.flags[l] = 0;
      rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcInitIntersectContext(&ctx);
    if (occluded) {
      rtcOccluded16(valid, scene, &ctx, &rh.ray);
      for (size_t l = 0; l < n; ++l) count += rh.ray.tfar[l] < 0.0f;
    } else {
      rtcIntersect16(valid, scene, &ctx, &rh);
      for (size_t l = 0; l < n; ++l) count += rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
    }
  }
  return count;
}

// Seconds of one pass over all rays on `threads` threads (chunks of 1024 rays taken in
// turn, a multiple of 16 so that packets are the same as on one thread), and the count.
std::pair<double, long> pass(RTCScene scene, const std::vector<RayRecord>& rays, bool occluded, bool packet,
                             unsigned threads) {
  const size_t chunk = 1024;
  const double start = now();
  if (threads == 1) {
    long count = trace(scene, rays, 0, rays.size(), occluded, packet);
    return {now() - start, count};
  }
  std::vector<long> counts(threads, 0);
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      for (size_t at = t * chunk; at < rays.size(); at += threads * chunk)
        counts[t] += trace(scene, rays, at, std::min(rays.size(), at + chunk), occluded, packet);
    });
  }
  for (auto& th : pool) th.join();
  long count = 0;
  for (long c : counts) count += c;
  return {now() - start, count};
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) fail("usage: embree-rays DIR [--reps N] [--threads N] [--robust]");
  const std::string dir = argv[1];
  int reps = 5;
  unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  bool robust = false;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--reps" && i + 1 < argc) reps = std::max(1, std::atoi(argv[++i]));
    else if (a == "--threads" && i + 1 < argc) threads = unsigned(std::max(1, std::atoi(argv[++i])));
    else if (a == "--robust") robust = true;
    else fail("unknown argument " + a);
  }
  std::vector<float> vertices;
  std::vector<unsigned> indices;
  read_obj(dir + "/scene.obj", vertices, indices);
  const std::string config = "threads=" + std::to_string(threads);
  RTCDevice device = rtcNewDevice(config.c_str());
  if (!device) fail("rtcNewDevice failed");
  RTCScene scene = rtcNewScene(device);
  if (robust) rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
  RTCGeometry geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                         3 * sizeof(float), vertices.size() / 3));
  std::memcpy(vb, vertices.data(), vertices.size() * sizeof(float));
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                            3 * sizeof(unsigned), indices.size() / 3));
  std::memcpy(ib, indices.data(), indices.size() * sizeof(unsigned));
  rtcCommitGeometry(geometry);
  rtcAttachGeometry(scene, geometry);
  rtcReleaseGeometry(geometry);
  rtcCommitScene(scene);

  struct Set {
    const char* name;
    bool occluded;
    std::vector<RayRecord> rays;
  };
  std::vector<Set> sets;
  for (auto [name, occluded] : {std::pair{"paths", false}, std::pair{"shadow", true}}) {
    std::ifstream probe(dir + "/" + name + ".rays");
    if (probe) sets.push_back({name, occluded, read_rays(dir + "/" + name + ".rays")});
  }
  if (sets.empty()) fail(dir + ": no paths.rays or shadow.rays (lightpath render --record-rays DIR)");

  std::printf("{\"tool\": \"embree-rays\", \"embree\": \"%d.%d.%d\", \"triangles\": %zu, \"robust\": %s,\n",
              RTC_VERSION_MAJOR, RTC_VERSION_MINOR, RTC_VERSION_PATCH, indices.size() / 3,
              robust ? "true" : "false");
  std::printf(" \"traversal\": {");
  const unsigned variants[2] = {1, threads};
  for (int v = 0; v < 2; ++v) {
    std::printf("%s\n  \"%s\": {\"threads\": %u", v ? "," : "", v ? "mt" : "st", variants[v]);
    for (int packet = 0; packet < 2; ++packet) {
      if (packet) std::printf(", \"packet\": {");
      for (size_t s = 0; s < sets.size(); ++s) {
        const Set& set = sets[s];
        long count = pass(scene, set.rays, set.occluded, packet, variants[v]).second;  // warm-up
        std::vector<double> times;
        for (int r = 0; r < reps; ++r) times.push_back(pass(scene, set.rays, set.occluded, packet, variants[v]).first);
        std::sort(times.begin(), times.end());
        const double n = double(set.rays.size());
        std::printf("%s\"%s\": {\"rays\": %zu, \"hits\": %ld, \"mrays_per_s_median\": %.4f, \"mrays_per_s_best\": %.4f}",
                    (packet && s == 0) ? "" : ", ", set.name, set.rays.size(), count, n / times[times.size() / 2] / 1e6,
                    n / times[0] / 1e6);
      }
      if (packet) std::printf("}");
    }
    std::printf("}");
  }
  std::printf("\n }\n}\n");
  rtcReleaseScene(scene);
  rtcReleaseDevice(device);
  return 0;
}
