// Where libtorch's CPU tensors get their memory (private to gdr_neural).
#pragma once

namespace gdr::neural {

/// Makes libtorch allocate CPU tensor storage of 1 MiB and more with
/// gdr::detail::large_alloc (2 MiB-aligned mappings with huge-page advice;
/// smaller blocks from operator new). Idempotent and thread-safe; process-wide, as
/// libtorch's allocator is. Why: a 1280x720 forward pass allocates about
/// 1.5 GB of fresh activations, and page faults on them cost more than the
/// convolutions on a virtual machine (see the header for measurements).
void use_large_page_tensors();

}  // namespace gdr::neural
