"""hallhome benchmark suite: the paper's figures on the native closed loop and
the simavr bench, with plots and a Markdown report (docs/benchmarks.md)."""
