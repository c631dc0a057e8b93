#include "hal/device.hpp"

namespace hapticloth::devices {

const char* to_string(Status s) {
  switch (s) {
    case Status::Ok: return "ok";
    case Status::NoData: return "no_data";
    case Status::Error: return "error";
  }
  return "?";
}

const char* to_string(Lifecycle s) {
  switch (s) {
    case Lifecycle::Unconfigured: return "unconfigured";
    case Lifecycle::Inactive: return "inactive";
    case Lifecycle::Active: return "active";
    case Lifecycle::Failed: return "failed";
  }
  return "?";
}

}  // namespace hapticloth::devices
