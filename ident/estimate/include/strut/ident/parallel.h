// Work spread over threads, the same result for any thread count: every task writes only its own
// slot, and the caller combines the slots in task order.
#pragma once

#include <functional>

namespace strut::ident {

//! Runs f(0) .. f(count - 1) on up to `threads` threads (the calling one among them); a thread takes
//! the next task as it finishes one, so tasks of unequal length keep every thread busy. The first
//! exception is rethrown once every task has ended.
void ParallelFor(int count, int threads, const std::function<void(int)>& f);

}  // namespace strut::ident
