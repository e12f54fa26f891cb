"""Built-in cases: the case files shipped with the package (``data/*.toml``) and their exact,
analytic or reference solutions (``exact``, ``flow_exact``, ``penny_exact``, ``reference``)."""
