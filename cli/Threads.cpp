#include "Threads.hpp"

#include <cstddef>
#include <memory>

#include <tbb/global_control.h>

namespace isohex::cli {

namespace {
std::unique_ptr<tbb::global_control>& threadLimit() {
    static std::unique_ptr<tbb::global_control> limit;
    return limit;
}
}  // namespace

void applyThreads(int threads) {
    if (threads > 0)
        threadLimit() = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                              static_cast<std::size_t>(threads));
}

}  // namespace isohex::cli
