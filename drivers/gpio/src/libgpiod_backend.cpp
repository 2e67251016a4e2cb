// The GpioBackend over libgpiod 1.6: one bulk request per chip.
#include "photorig/drivers/gpio/gpio_lights.h"

#include <gpiod.h>

#include <cerrno>
#include <cstring>
#include <map>

namespace photorig::drivers {
namespace {

class LibgpiodBackend : public GpioBackend {
 public:
  ~LibgpiodBackend() override { Release(); }

  Status Request(const std::string& consumer, const std::vector<GpioLine>& lines,
                 const std::vector<int>& initial) override {
    Release();
    for (std::size_t i = 0; i < lines.size(); ++i) {
      Group* group = nullptr;
      for (Group& g : groups_)
        if (g.name == lines[i].chip) group = &g;
      if (!group) {
        group = &groups_.emplace_back();
        group->name = lines[i].chip;
      }
      group->offsets.push_back(lines[i].offset);
      group->initial.push_back(initial[i]);
      group->indices.push_back(i);
    }
    for (Group& group : groups_) {
      group.chip = gpiod_chip_open_lookup(group.name.c_str());
      if (!group.chip) return Fail("cannot open GPIO chip '" + group.name + "'");
      if (group.offsets.size() > GPIOD_LINE_BULK_MAX_LINES) return Fail("too many lines on " + group.name);
      if (gpiod_chip_get_lines(group.chip, group.offsets.data(), group.offsets.size(), &group.bulk) != 0)
        return Fail("no such line on " + group.name);
      if (gpiod_line_request_bulk_output(&group.bulk, consumer.c_str(), group.initial.data()) != 0)
        return Fail("cannot request lines on " + group.name + " (busy?)");
      group.requested = true;
    }
    count_ = lines.size();
    return Status::Ok();
  }

  Status Set(const std::vector<int>& physical) override {
    for (Group& group : groups_) {
      std::vector<int> values;
      for (std::size_t index : group.indices) values.push_back(physical.at(index));
      if (gpiod_line_set_value_bulk(&group.bulk, values.data()) != 0) return Fail("set lines on " + group.name);
    }
    return Status::Ok();
  }

  Result<std::vector<int>> Get() override {
    std::vector<int> physical(count_);
    for (Group& group : groups_) {
      std::vector<int> values(group.indices.size());
      if (gpiod_line_get_value_bulk(&group.bulk, values.data()) != 0) return Fail("read lines on " + group.name);
      for (std::size_t k = 0; k < values.size(); ++k) physical[group.indices[k]] = values[k];
    }
    return physical;
  }

  void Release() override {
    for (Group& group : groups_) {
      if (group.requested) gpiod_line_release_bulk(&group.bulk);
      if (group.chip) gpiod_chip_close(group.chip);
    }
    groups_.clear();
    count_ = 0;
  }

 private:
  struct Group {
    std::string name;
    gpiod_chip* chip = nullptr;
    gpiod_line_bulk bulk{};
    bool requested = false;
    std::vector<unsigned> offsets;
    std::vector<int> initial;
    std::vector<std::size_t> indices;
  };
  Status Fail(const std::string& what) const {
    return {StatusCode::kUnavailable, "gpio: " + what + ": " + std::strerror(errno)};
  }

  std::vector<Group> groups_;  // all pushed before any bulk is filled, so bulks never move
  std::size_t count_ = 0;
};

}  // namespace

std::unique_ptr<GpioBackend> MakeLibgpiodBackend() { return std::make_unique<LibgpiodBackend>(); }

}  // namespace photorig::drivers
