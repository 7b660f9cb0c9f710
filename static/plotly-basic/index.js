// plotly.js's basic bundle (scatter, bar and pie traces; plotly-basic.min.js, v3.7.0, MIT: LICENSE, as npm's
// plotly.js-basic-dist-min publishes it, unchanged) as the module the charts import. Its loader, run as a module,
// finds no CommonJS module and leaves the library on self.moduleName: taken from there, the global removed.
import "./plotly-basic.min.js";

const Plotly = self.moduleName;
delete self.moduleName;

export { Plotly };
