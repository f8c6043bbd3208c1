// The API's documentation page (/docs): Swagger UI on this server's openapi.json. A file,
// not an inline script, so that the page's policy allows scripts from this server only.
window.ui = SwaggerUIBundle({
  url: new URL('openapi.json', document.baseURI).href,
  dom_id: '#swagger-ui',
  layout: 'BaseLayout',
  deepLinking: true,
  showExtensions: true,
  showCommonExtensions: true,
  validatorUrl: null, // never ask validator.swagger.io about our description
  presets: [SwaggerUIBundle.presets.apis],
});
