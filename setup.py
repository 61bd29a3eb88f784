"""Package layout (the metadata is in pyproject.toml): the layers' folders stand at the top of the repository
(estimators/, warehouse/, pipeline/, ...) and are installed and imported as ``stridelab.<layer>``
(setuptools ``package_dir``), so that ``stridelab`` is the only name StrideLab puts at the top of
site-packages. See docs/architecture.md "One installed name".

The list of packages is found here rather than in pyproject.toml because ``[tool.setuptools.packages.find]``
cannot prefix what it finds; data-only folders (migrations, models, static files, study manifests) are
namespace packages so that their files ship (``[tool.setuptools.package-data]``).
"""
from setuptools import find_namespace_packages, setup

NAMESPACE = "stridelab"
LAYERS = ("estimators", "warehouse", "pipeline", "reports", "dashboard", "validation", "studies")

packages = [NAMESPACE] + find_namespace_packages(include=[f"{NAMESPACE}.*"])
package_dir = {NAMESPACE: NAMESPACE}
for layer in LAYERS:
    found = find_namespace_packages(include=[layer, f"{layer}.*"])
    packages += [f"{NAMESPACE}.{p}" for p in found]
    package_dir[f"{NAMESPACE}.{layer}"] = layer

setup(packages=packages, package_dir=package_dir)
