// autodrive-eye register and localize: the offline commands on frames from files.
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "common/error.h"
#include "eye/commands.h"
#include "eye/localizer.h"
#include "eye/registration.h"
#include "eye/sources.h"

namespace autodrive::eye::cli {

namespace {

// The configuration with the camera's source replaced by --images / --video, when given.
EyeConfig WithOverride(EyeConfig config, const std::string& camera, const std::string& images,
                       const std::string& video) {
  if (images.empty() && video.empty()) return config;
  AUTODRIVE_THROW_UNLESS(images.empty() || video.empty(), "give --images or --video, not both");
  std::size_t index = 0;
  if (camera.empty()) {
    AUTODRIVE_THROW_UNLESS(config.cameras.size() == 1, "the configuration has "
                                                           << config.cameras.size()
                                                           << " cameras: name the one --images or "
                                                              "--video is for with --camera");
  } else {
    bool found = false;
    for (std::size_t i = 0; i < config.cameras.size(); ++i) {
      if (config.cameras[i].name == camera) {
        index = i;
        found = true;
      }
    }
    AUTODRIVE_THROW_UNLESS(found, "no camera \"" << camera << "\" in the configuration");
  }
  config.cameras[index].source = images.empty() ? "video:" + video : "images:" + images;
  return config;
}

// Registers every camera without a pose from the full-frame detections of its first frames.
// Returns false (with the reasons printed) when one could not be.
bool RegisterFromFirstFrames(Localizer& localizer, bool quiet, const std::string& save_dir) {
  bool ok = true;
  const EyeConfig& config = localizer.config();
  for (std::size_t c = 0; c < localizer.camera_count(); ++c) {
    if (localizer.registered(c) && save_dir.empty()) continue;
    const auto source = OpenSource(config.cameras[c]);
    std::vector<std::vector<TagDetection>> frames;
    TagDetector detector(config.detector);
    while (static_cast<int>(frames.size()) < config.registration.frames) {
      const auto frame = source->Next();
      if (!frame) break;
      if (!frame->unreadable.empty()) continue;  // localize reports it when it comes to it
      frames.push_back(detector.Detect(ToGrey(frame->image)));
    }
    std::string why;
    const auto r = localizer.Register(c, frames, &why);
    const std::string& name = config.cameras[c].name;
    if (!r) {
      std::fprintf(stderr, "autodrive-eye: camera %s: registration failed: %s\n", name.c_str(),
                   why.c_str());
      ok = false;
      continue;
    }
    const Eigen::Vector3d p = r->X_MC.translation();
    if (!quiet) {
      std::string ids;
      for (int id : r->tag_ids) ids += (ids.empty() ? "" : " ") + std::to_string(id);
      std::fprintf(stderr,
                   "autodrive-eye: camera %s registered from %zu reference tags (%s) over %d "
                   "frames: %.3f px RMS, max %.3f px; position (%.4f, %.4f, %.4f) m\n",
                   name.c_str(), r->tag_ids.size(), ids.c_str(), r->frames, r->rms_px, r->max_px,
                   p.x(), p.y(), p.z());
    }
    if (!save_dir.empty()) {
      const std::filesystem::path out = std::filesystem::path(save_dir) / (name + "_pose.yaml");
      SavePose(out, name, name, *r);
      if (!quiet) std::fprintf(stderr, "autodrive-eye: wrote %s\n", out.string().c_str());
    }
  }
  return ok;
}

std::string Number(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.6f", v);
  return buffer;
}

// The poses' CSV file: written as FILE.partial and renamed to FILE at a clean end, so that a
// FILE there is always a whole run's. An older FILE is removed when the run starts.
class PosesFile {
 public:
  explicit PosesFile(const std::string& path) : path_(path), partial_(path + ".partial") {
    std::error_code ec;
    std::filesystem::remove(path_, ec);
    AUTODRIVE_THROW_UNLESS(!ec, path_ << ": cannot remove the older file: " << ec.message());
    out_.open(partial_);
    AUTODRIVE_THROW_UNLESS(out_.good(), partial_ << ": cannot write");
    out_ << "frame,stamp_s,vehicle,tag_id,x_m,y_m,yaw_rad,camera\n";
  }
  std::ofstream& out() { return out_; }
  [[nodiscard]] const std::string& partial() const { return partial_; }
  // Closes the file and gives it its name.
  void Commit() {
    out_.close();
    AUTODRIVE_THROW_UNLESS(!out_.fail(), partial_ << ": writing failed");
    std::filesystem::rename(partial_, path_);
  }

 private:
  std::string path_;
  std::string partial_;
  std::ofstream out_;
};

// What a run read, skipped and localised.
struct Tally {
  long long frames = 0;              // frame indices (one frame of each camera)
  long long read = 0;                // cameras' frames read and searched
  std::vector<std::string> skipped;  // "file" (one camera) or "camera: file"
  std::vector<long long> localized;  // per car: frames it was localised in
  long long rows = 0;

  // `localize: summary: ...`, one line.
  [[nodiscard]] std::string Summary(const EyeConfig& config) const {
    std::string names;
    constexpr std::size_t kNamed = 20;
    for (std::size_t i = 0; i < skipped.size() && i < kNamed; ++i) {
      names += (i == 0 ? "" : ", ") + skipped[i];
    }
    if (skipped.size() > kNamed)
      names += ", and " + std::to_string(skipped.size() - kNamed) + " more";
    std::string cars;
    for (std::size_t v = 0; v < config.vehicles.size(); ++v) {
      cars += (v == 0 ? "" : ", ") + config.vehicles[v].name + " " + std::to_string(localized[v]);
    }
    char per_frame[32];
    std::snprintf(per_frame, sizeof per_frame, "%.2f",
                  frames > 0 ? static_cast<double>(rows) / static_cast<double>(frames) : 0.0);
    return "localize: summary: " + std::to_string(read) + " frames read, " +
           std::to_string(skipped.size()) + " skipped" +
           (skipped.empty() ? std::string() : " (" + names + ")") + ", " + per_frame +
           " cars localised per frame (" + cars + ")";
  }
};

void PrintEvents(const std::vector<EyeEvent>& events) {
  for (const EyeEvent& e : events) {
    std::fprintf(stderr, "localize: event at %.3f s: %s%s %s: %s\n", ToSeconds(e.stamp),
                 ToString(e.kind), e.cleared ? " (cleared)" : "", e.subject.c_str(),
                 e.text.c_str());
  }
}

// One frame index: each camera's frame localised; the cars seen, with the cameras that saw each.
// False when no camera had a frame left. Throws InputError for an unreadable frame when
// `strict`.
bool LocalizeIndex(Localizer& localizer, std::vector<std::unique_ptr<FrameSource>>& sources,
                   bool strict, std::vector<EyeEvent>& events, Tally& tally,
                   std::map<std::size_t, LocalizedVehicle>& seen, std::optional<Frame>& first) {
  const EyeConfig& config = localizer.config();
  bool any = false;
  std::vector<std::size_t> withdrawn;
  for (std::size_t c = 0; c < sources.size(); ++c) {
    auto frame = sources[c]->Next();
    if (!frame) continue;
    any = true;
    std::vector<LocalizedVehicle> cars;
    if (frame->unreadable.empty()) {
      try {
        cars = localizer.LocalizeFrame(c, frame->stamp, frame->image, &events, &withdrawn);
      } catch (const InputError& e) {
        frame->unreadable = e.what();  // a frame of the wrong size or type: not searchable
      }
    }
    if (!frame->unreadable.empty()) {
      const std::string name =
          sources.size() == 1 ? frame->name : config.cameras[c].name + ": " + frame->name;
      AUTODRIVE_THROW_UNLESS(!strict, "camera " << config.cameras[c].name << ": " << frame->name
                                                << ": unreadable frame (" << frame->unreadable
                                                << ")");
      tally.skipped.push_back(name);
      std::fprintf(stderr, "localize: warning: camera %s: %s skipped: %s\n",
                   config.cameras[c].name.c_str(), frame->name.c_str(), frame->unreadable.c_str());
    } else {
      ++tally.read;
    }
    for (std::size_t v : withdrawn) seen.erase(v);  // another camera saw its id elsewhere
    withdrawn.clear();
    for (LocalizedVehicle& l : cars) {
      auto [it, fresh] = seen.try_emplace(l.vehicle, l);
      if (!fresh) {
        it->second.estimate = l.estimate;
        it->second.cameras.push_back(c);
      }
    }
    if (!first) first = std::move(frame);
  }
  return any;
}

int Localize(const std::string& config_path, const std::string& camera, const std::string& images,
             const std::string& video, const std::string& out_path, bool quiet, bool strict) {
  const EyeConfig config = WithOverride(LoadEyeConfig(config_path), camera, images, video);
  Localizer localizer(config);
  if (!RegisterFromFirstFrames(localizer, quiet, "")) return 1;
  std::vector<std::unique_ptr<FrameSource>> sources;
  for (const CameraConfig& c : config.cameras) sources.push_back(OpenSource(c));
  PosesFile file(out_path);
  const bool tty = isatty(fileno(stderr)) != 0;
  Tally tally;
  tally.localized.assign(config.vehicles.size(), 0);
  std::vector<EyeEvent> events;
  for (;;) {
    // One frame of every camera (the frames of one index were taken together).
    std::map<std::size_t, LocalizedVehicle> seen;
    std::optional<Frame> first;
    try {
      if (!LocalizeIndex(localizer, sources, strict, events, tally, seen, first)) break;
    } catch (const InputError& e) {
      if (!quiet) PrintEvents(events);
      std::fprintf(stderr,
                   "%sautodrive-eye localize: %s; stopped there (--strict): the poses of the "
                   "frames before it are in %s, %s was not written\n",
                   tty ? "\r" : "", e.what(), file.partial().c_str(), out_path.c_str());
      return 1;
    }
    for (const auto& [v, l] : seen) {
      std::string cameras;
      for (std::size_t c : l.cameras) {
        cameras += (cameras.empty() ? "" : "+") + config.cameras[c].name;
      }
      const VehicleTagConfig& vehicle = config.vehicles[v];
      file.out() << first->index << ',' << Number(ToSeconds(first->stamp)) << ',' << vehicle.name
                 << ',' << vehicle.tag_id << ',' << Number(l.estimate.tag_centre_M.x()) << ','
                 << Number(l.estimate.tag_centre_M.y()) << ',' << Number(l.estimate.pose.z()) << ','
                 << cameras << '\n';
      ++tally.localized[v];
      ++tally.rows;
    }
    ++tally.frames;
    if (!quiet && (tty || tally.frames % 100 == 0)) {
      std::fprintf(stderr, "%slocalize: %lld frames%s", tty ? "\r" : "", tally.frames,
                   tty ? "" : "\n");
    }
  }
  file.Commit();
  if (!quiet) {
    const LocalizerCounters n = localizer.counters();
    std::fprintf(stderr,
                 "%slocalize: %lld frames of %zu camera(s), %lld full scans, %.1f Mpx "
                 "searched, %lld outliers, %lld unknown tags, %lld refused poses, %lld refused "
                 "as duplicated ids\n",
                 tty ? "\r" : "", tally.frames, sources.size(), n.full_scans,
                 static_cast<double>(n.pixels_searched) / 1e6, n.outliers, n.unknown_tags,
                 n.refused_poses, n.duplicate_refusals);
    for (std::size_t v = 0; v < config.vehicles.size(); ++v) {
      std::fprintf(stderr, "localize: %s localized in %lld of %lld frames\n",
                   config.vehicles[v].name.c_str(), tally.localized[v], tally.frames);
    }
    PrintEvents(events);
    std::fprintf(stderr, "%s\n", tally.Summary(config).c_str());
    std::fprintf(stderr, "localize: wrote %s\n", out_path.c_str());
  }
  return 0;
}

// The options `register` and `localize` share: the configuration and where one camera's frames
// come from instead of its source.
struct FrameOptions {
  std::string config;
  std::string camera;
  std::string images;
  std::string video;
  bool quiet = false;
  bool strict = false;
};

std::shared_ptr<FrameOptions> AddFrameOptions(CLI::App* cmd) {
  auto o = std::make_shared<FrameOptions>();
  cmd->add_option("--config", o->config,
                  "the Eye's configuration, or a city file with an eye section")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--camera", o->camera, "the camera --images or --video is for");
  cmd->add_option("--images", o->images, "a folder of frames instead of the camera's source")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--video", o->video, "a video file instead of the camera's source")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--quiet", o->quiet, "print only errors and warnings (frames skipped)");
  return o;
}

}  // namespace

void AddRegister(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "register",
      "register each camera to the map from the reference tags on the ground: detects them in "
      "the first frames (registration.frames) of the camera's source, solves for its pose and "
      "writes CAMERA_pose.yaml per camera into --out-dir (set a camera's `pose` to it)");
  const auto o = AddFrameOptions(cmd);
  auto out_dir = std::make_shared<std::string>();
  cmd->add_option("--out-dir", *out_dir, "where to write CAMERA_pose.yaml")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->callback([o, out_dir] {
    EyeConfig c = WithOverride(LoadEyeConfig(o->config), o->camera, o->images, o->video);
    for (CameraConfig& cam : c.cameras) cam.pose.reset();  // register afresh
    Localizer localizer(c);
    if (!RegisterFromFirstFrames(localizer, o->quiet, *out_dir)) throw CLI::RuntimeError(1);
  });
}

void AddLocalize(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "localize",
      "localize the fleet in frames from files and write POSES.csv: "
      "frame,stamp_s,vehicle,tag_id,x_m,y_m,yaw_rad,camera, one row per car per frame in which "
      "it was seen; (x_m, y_m) is the centre of the car's roof tag, yaw_rad the car's heading "
      "(docs/eye.md). Cameras without a pose are registered from their first frames first. "
      "Unreadable frames are counted and skipped with a warning (--strict: stop at one); the "
      "run ends with a summary line: frames read, skipped (named), cars localised per frame");
  const auto o = AddFrameOptions(cmd);
  auto out = std::make_shared<std::string>();
  cmd->add_option("--out", *out,
                  "the poses' CSV file to write: written as FILE.partial and renamed to FILE "
                  "at a clean end (an older FILE is removed first)")
      ->required();
  cmd->add_flag("--strict", o->strict,
                "stop at the first unreadable frame (exit status 1; FILE.partial stays, FILE "
                "is not written) instead of skipping it with a warning");
  cmd->callback([o, out] {
    const int status =
        Localize(o->config, o->camera, o->images, o->video, *out, o->quiet, o->strict);
    if (status != 0) throw CLI::RuntimeError(status);
  });
}

}  // namespace autodrive::eye::cli
