#include "common/camera/tag_family.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include <map>
#include <utility>

#include "common/error.h"

namespace autodrive::camera {

namespace {

struct Entry {
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

const std::map<std::string, Entry, std::less<>>& Table() {
  static const std::map<std::string, Entry, std::less<>> kTable{
      {"tag16h5", {tag16h5_create, tag16h5_destroy}},
      {"tag25h9", {tag25h9_create, tag25h9_destroy}},
      {"tag36h10", {tag36h10_create, tag36h10_destroy}},
      {"tag36h11", {tag36h11_create, tag36h11_destroy}},
      {"tagCircle21h7", {tagCircle21h7_create, tagCircle21h7_destroy}},
      {"tagCircle49h12", {tagCircle49h12_create, tagCircle49h12_destroy}},
      {"tagCustom48h12", {tagCustom48h12_create, tagCustom48h12_destroy}},
      {"tagStandard41h12", {tagStandard41h12_create, tagStandard41h12_destroy}},
      {"tagStandard52h13", {tagStandard52h13_create, tagStandard52h13_destroy}},
  };
  return kTable;
}

}  // namespace

TagFamily::TagFamily(std::string_view name) : name_(name) {
  const auto it = Table().find(name);
  if (it == Table().end()) {
    std::string names;
    for (const std::string& n : Names()) names += (names.empty() ? "" : ", ") + n;
    throw InputError("unknown AprilTag family \"" + name_ + "\" (known: " + names + ")");
  }
  family_ = it->second.create();
  destroy_ = it->second.destroy;
}

TagFamily::~TagFamily() {
  if (family_ != nullptr) destroy_(family_);
}

TagFamily::TagFamily(TagFamily&& other) noexcept
    : name_(std::move(other.name_)),
      family_(std::exchange(other.family_, nullptr)),
      destroy_(other.destroy_) {}

TagFamily& TagFamily::operator=(TagFamily&& other) noexcept {
  if (this != &other) {
    if (family_ != nullptr) destroy_(family_);
    name_ = std::move(other.name_);
    family_ = std::exchange(other.family_, nullptr);
    destroy_ = other.destroy_;
  }
  return *this;
}

int TagFamily::codes() const { return static_cast<int>(family_->ncodes); }
int TagFamily::total_width() const { return family_->total_width; }
int TagFamily::width_at_border() const { return family_->width_at_border; }

void TagFamily::CheckId(int id) const {
  if (id < 0 || id >= codes()) {
    throw InputError("AprilTag family " + name_ + " has ids 0.." + std::to_string(codes() - 1) +
                     ", not " + std::to_string(id));
  }
}

std::vector<std::string> TagFamily::Names() {
  std::vector<std::string> names;
  for (const auto& [name, entry] : Table()) names.push_back(name);
  return names;
}

}  // namespace autodrive::camera
