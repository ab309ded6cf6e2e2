"""The flagship's kernels through deltafmi's code generator (deltafmi/builder/codegen), closed in a
hand-written C loop (:mod:`.flagship`); measured by ``benchmarks/kernel_codegen_flagship.py``."""
