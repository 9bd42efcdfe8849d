#include <limits>

#include <fmt/core.h>

#include "gdr/cli/commands.h"
#include "gdr/cli/plugins.h"
#include "render_options.h"
#include "say.h"
#include "gdr/core/error.h"
#include "gdr/io/scene_file.h"
#include "gdr/shift/validate.h"

namespace gdr::cli {

int check_shift(const std::vector<std::string>& args) {
    ArgReader a{args};
    std::string scene_path, shift_name = "half-vector", integrator = "gpt";
    ValidateOptions opt;
    ShiftConfig cfg;
    SceneFileOptions scene_options;
    Params shift_params("gdr check-shift --set");
    while (a.more()) {
        const std::string o = a.next();
        if (o == "-h" || o == "--help") return print_usage("check-shift");
        if (o == "--shift") shift_name = a.value(o);
        else if (o == "--integrator") {
            integrator = a.value(o);
            if (integrator != "gpt" && integrator != "gbdpt")
                throw ParameterError("check-shift: --integrator must be gpt or gbdpt, got '" + integrator + "'");
        }
        else if (o == "--paths") opt.paths = int(a.int_value(o, 1, std::numeric_limits<int>::max()));
        else if (o == "--seed") opt.seed = uint64_t(a.int_value(o, 0, std::numeric_limits<long long>::max()));
        else if (o == "--max-depth") {
            opt.max_depth = int(a.int_value(o, -1, 1024));
            if (opt.max_depth == 0) throw ParameterError("option --max-depth must be -1 (unlimited) or >= 1, got 0");
        }
        else if (o == "--threshold") {
            cfg.threshold = float(a.real_value(o));
            if (cfg.threshold < 0.f) throw ParameterError("option --threshold must be >= 0");
        }
        else if (o == "--probabilistic") cfg.probabilistic = true;
        else if (o == "--set") shift_params.set_from_text(a.value(o));
        else if (o == "-D") add_define(scene_options, a.value(o));
        else if (o == "--lenient") scene_options.lenient = true;
        else if (!o.empty() && o[0] == '-') throw ParameterError("check-shift: unknown option '" + o + "'\n" + usage("check-shift"));
        else if (scene_path.empty()) scene_path = o;
        else throw ParameterError("check-shift: unexpected argument '" + o + "'");
    }
    if (scene_path.empty()) throw ParameterError("check-shift: no scene file given\n" + usage("check-shift"));
    const SceneFile sf = load_scene_file(scene_path, scene_options);
    for (const std::string& w : sf.warnings) say("warning: {}\n", w);
    require_shift(shift_name, "gdr check-shift --shift " + shift_name);
    const auto shift = shift_registry().create(shift_name, shift_params);
    const ShiftReport rep = integrator == "gbdpt" ? validate_bidirectional_shift(*sf.scene, *shift, cfg, opt)
                                                  : validate_shift(*sf.scene, *shift, cfg, opt);
    fmt::print("{}: {}", scene_path, rep.summary());
    return rep.passed ? 0 : 1;
}

}  // namespace gdr::cli
