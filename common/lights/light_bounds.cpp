#include "common/lights/light_bounds.h"

#include <tbb/parallel_for.h>

#include "common/scene/fresnel.h"

namespace lightfarm {

LobeBound MaterialLobeBound(const Material& m, Vec3 wo, TransportMode mode) {
  LobeBound b;
  if (wo.z == 0) return b;
  const float abs_cos_o = std::abs(wo.z);
  auto set_glossy = [&] {
    b.glossy = true;
    b.alpha_x = m.alpha_x;
    b.alpha_y = m.alpha_y;
    b.glossy_scale = 1.f / (4 * abs_cos_o);
  };
  switch (m.type) {
    case MaterialType::kDiffuse:
      b.diffuse_front = m.reflectance * kInvPi;
      break;
    case MaterialType::kDiffuseTransmission:
      b.diffuse_front = m.reflectance * kInvPi;
      b.diffuse_back = m.transmittance * kInvPi;
      break;
    case MaterialType::kCoatedDiffuse: {
      // The base's largest value is near the normal (see the header comment).
      Vec3 wo_up = wo.z < 0 ? -wo : wo;
      RGB at_normal = EvalBSDF(m, wo_up, Vec3(0, 0, 1), mode);
      float eta = m.eta.r > 0 ? m.eta.r : 1.f;
      float f0 = FrDielectric(1.f, eta);
      float e_normal = IsSmoothMaterial(m) ? f0 : std::min(0.5f, 4 * f0 + 0.02f);
      b.diffuse_front = at_normal * ((1 + 1e-3f) / (1 - e_normal));
      if (!ActsAsDelta(m)) set_glossy();  // a sharp coat is sampled, not gathered
      break;
    }
    case MaterialType::kConductor:
      if (!ActsAsDelta(m)) set_glossy();
      break;
    case MaterialType::kDielectric:
      if (m.eta.r != 1.f && !ActsAsDelta(m)) {
        set_glossy();
        b.back_unbounded = true;
      }
      break;
    case MaterialType::kThinDielectric:
    case MaterialType::kInterface:
      break;
  }
  return b;
}

EmissionBound LightEmissionBound(const VirtualLight& l, const std::vector<Material>& materials) {
  EmissionBound e;
  switch (l.kind) {
    case VirtualLightKind::kAreaVPL:
      e.diffuse_front = 1;
      if (l.two_sided) e.diffuse_back = 1;
      break;
    case VirtualLightKind::kSurfaceVPL: {
      // The tree's cone holds n flipped to the side of wi: "front" is the reflection side.
      Vec3 n = FaceForward(l.n, l.wi);
      Frame frame(n);
      LobeBound b = MaterialLobeBound(materials[l.material], frame.ToLocal(l.wi),
                                      TransportMode::kImportance);
      e.diffuse_front = b.diffuse_front.Max();
      e.diffuse_back = b.diffuse_back.Max();
      if (b.glossy) {
        e.glossy_peak = MicrofacetPeakScale(b.alpha_x, b.alpha_y) * b.glossy_scale;
        e.glossy_alpha = std::max(std::max(b.alpha_x, b.alpha_y), 1e-4f);
        e.mirror_axis = n * (2 * Dot(l.wi, n)) - l.wi;
        e.mirror_cos = 1;
      }
      e.back_unbounded = b.back_unbounded;
      break;
    }
    case VirtualLightKind::kPoint:
    case VirtualLightKind::kDirectional:
    case VirtualLightKind::kMediumVPL:  // never generated for lightcuts (render_job.cpp)
    case VirtualLightKind::kVRL:        // likewise
      e.diffuse_front = 1;  // unused: these kinds have no emission-side factor above 1
      break;
  }
  return e;
}

std::vector<EmissionBound> ComputeEmissionBounds(const LightTree& tree, const LightSet& lights,
                                                 const std::vector<Material>& materials) {
  const std::vector<LightTreeNode>& nodes = tree.nodes();
  std::vector<EmissionBound> bounds(nodes.size());
  tbb::parallel_for(size_t(0), nodes.size(), [&](size_t i) {
    if (nodes[i].IsLeaf())
      bounds[i] = LightEmissionBound(lights.lights[nodes[i].representative], materials);
  });
  // Children follow their parent in pre-order: a reverse sweep sees them first.
  for (size_t i = nodes.size(); i-- > 0;) {
    const LightTreeNode& n = nodes[i];
    if (n.IsLeaf()) continue;
    bounds[i] = bounds[size_t(n.left)];
    bounds[i].Max(bounds[size_t(n.right)]);
  }
  return bounds;
}

}  // namespace lightfarm
