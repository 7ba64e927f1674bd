// An error the viewer's HTTP layer answers with its status code and a JSON body {"error": message}.
#pragma once
#include <stdexcept>
#include <string>

namespace uplvsm::serve {

struct HttpError : std::runtime_error {
  int status;
  HttpError(int status_code, const std::string& message) : std::runtime_error(message), status(status_code) {}
};

}  // namespace uplvsm::serve
